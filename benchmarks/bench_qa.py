"""Issue 34's QA figure in one command: `urdf-pipeline qa` on the real G1 dataset lengthened 40x (bench_inputs.py's
`dataset` row: 100 episodes, ~1.44M frames) against reading its data once, and its memory against the same dataset
unlengthened (1x, ~36k frames). Every figure is the WHOLE command a user waits for, in its own process (interpreter
start and imports included): wall time, CPU seconds (user + sys of the child, os.wait4) and peak RSS.

  read  the reference: `python -c` compiling the config and calling `execute.segment_value_blocks` for every segment
        with a consumer that only iterates the blocks: the same reader, the same corrections, nothing measured.
        (`urdf-pipeline validate` reads no data, so it is no reference; `run` writes a recording, so it is a larger one.)
  qa    `urdf-pipeline qa CONFIG --format json -o FILE` (the report written to a file in the work directory)

The two ways run alternately, in ABBA order over --repeat rounds, at each length; the table shows ranges, medians and
the ratios qa/read of each round. Goals: qa ≤ 1.2x the read (CPU and wall); qa's peak RSS ≤ 1.1x the read's at both
lengths (qa holds a few rows and fixed-size histograms beyond the block the reader holds). The 40x/1x growth of both
peaks is the reader's block: bench_inputs.py writes each episode as one parquet row group, the unit the reader reads.
Usage: python benchmarks/bench_qa.py [--repeat 3] [--workdir DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_all import Runner, Sample, alternate, mb, spread, verdict

HERE = Path(__file__).resolve().parent
LENGTHS = {"x1": 1 / 40, "x40": 1.0}  # bench_inputs.py's --scale: the dataset row lengthens by 40 * scale
TIME_GOAL, MEMORY_GOAL = 1.2, 1.1
READ_ONCE = """
import sys
from pathlib import Path
from urdf_pipeline.compile import compile_config
from urdf_pipeline.execute import segment_value_blocks

def consume(robot, source, mapper, blocks):
    for _ in blocks:
        pass

plan = compile_config(Path(sys.argv[1]))
for segment in plan.segments:
    segment_value_blocks(plan.for_segment(segment), consume)
"""


def prepare(workdir: Path) -> dict[str, dict]:
    """Both lengths' inputs (reused when present); each gets its own copy of the config bench_inputs.py writes."""
    made = {}
    for name, scale in LENGTHS.items():
        command = [sys.executable, str(HERE / "bench_inputs.py"), str(workdir), "--rows", "dataset", "--scale", str(scale)]
        done = subprocess.run(command, stdout=subprocess.PIPE, text=True, check=True)
        spec = json.loads(done.stdout.strip().splitlines()[-1])["dataset"]
        if "skipped" in spec:
            raise SystemExit(f"bench_qa: {spec['skipped']}")
        config = workdir / f"g1_dataset_{name}.yaml"
        shutil.copyfile(spec["config"], config)
        made[name] = {**spec, "config": str(config)}
    return made


def cells(samples: list[Sample]) -> str:
    return f"{spread([s.seconds for s in samples], ' s')} wall, {spread([s.cpu for s in samples], ' s')} CPU, {mb(max(s.peak_mb for s in samples))}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3, help="rounds per length (default 3)")
    parser.add_argument("--workdir", type=Path, help="keep inputs (reused next time) and logs here (default: a temporary directory)")
    args = parser.parse_args()
    temporary = None if args.workdir else tempfile.TemporaryDirectory(prefix="bench-qa-")
    workdir = (args.workdir or Path(temporary.name)).resolve()  # type: ignore[union-attr]
    workdir.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()
    try:
        print(f"bench_qa: generating inputs in {workdir} ...", file=sys.stderr, flush=True)
        made = prepare(workdir)
        runner = Runner(workdir)
        subprocess.run(
            [sys.executable, "-m", "compileall", "-q", str(HERE.parent / "urdf_pipeline")], stdout=subprocess.DEVNULL, check=True
        )
        runner.measure([*runner.cli, "validate", *(spec["config"] for spec in made.values())], "validate")  # warms caches
        measured: dict[str, dict[str, list[Sample]]] = {}
        for name, spec in made.items():
            report = workdir / f"qa_{name}.json"
            print(f"bench_qa: {name} ({spec['frames']:,} frames), {args.repeat} round(s)", file=sys.stderr, flush=True)
            ways = {
                "read": lambda spec=spec, name=name: runner.measure([sys.executable, "-c", READ_ONCE, spec["config"]], f"{name}-read"),
                "qa": lambda spec=spec, name=name, report=report: runner.measure(
                    [*runner.cli, "qa", spec["config"], "--format", "json", "-o", str(report)], f"{name}-qa"
                ),
            }
            measured[name] = alternate(runner, args.repeat, ways)
        print()
        print(
            f"urdf-pipeline qa vs reading the data once (segment_value_blocks, no-op consumer), whole processes: "
            f"{args.repeat} round(s) in ABBA order; {os.cpu_count()} cores, load average {load[0]:.2f} before and "
            f"{os.getloadavg()[0]:.2f} after"
        )
        print()
        lines = ["| input | read once | qa | qa / read | goal |", "|---|---|---|---|---|"]
        for name, spec in made.items():
            read, qa = measured[name]["read"], measured[name]["qa"]
            walls = [q.seconds / r.seconds for q, r in zip(qa, read, strict=True)]
            cpus = [q.cpu / r.cpu for q, r in zip(qa, read, strict=True)]
            goal = f"≤ {TIME_GOAL}x: CPU {verdict(statistics.median(cpus) <= TIME_GOAL)}, wall {verdict(statistics.median(walls) <= TIME_GOAL)}"
            label = f"G1 dataset {name}, {spec['episodes']} episodes, {spec['frames']:,} frames"
            ratio = f"CPU {spread(cpus, 'x')}, wall {spread(walls, 'x')}"
            lines.append(f"| {label} | {cells(read)} | {cells(qa)} | {ratio} | {goal} |")
        for name in made:  # qa's memory beyond the reader's: what its own accumulators hold
            read_peak, qa_peak = (max(s.peak_mb for s in measured[name][way]) for way in ("read", "qa"))
            ok = qa_peak <= MEMORY_GOAL * read_peak
            lines.append(
                f"| peak RSS at {name} | {mb(read_peak)} | {mb(qa_peak)} | {qa_peak / read_peak:.2f}x | ≤ {MEMORY_GOAL}x the read's: {verdict(ok)} |"
            )
        growth = {way: max(s.peak_mb for s in measured["x40"][way]) / max(s.peak_mb for s in measured["x1"][way]) for way in ("read", "qa")}
        lines.append(f"| peak RSS, 40x / 1x | {growth['read']:.2f}x | {growth['qa']:.2f}x | | (the reader's block: one row group) |")
        print("\n".join(lines))
        print()
        print(f"logs in {workdir / 'logs'}" if args.workdir else "")
    finally:
        if temporary is not None:
            temporary.cleanup()


if __name__ == "__main__":
    main()

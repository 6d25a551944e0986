"""Issue 12's table in one command: every figure is the WHOLE command a user waits for, in its own process
(interpreter start and imports included), wall time and peak RSS.

  panda300k, panda1m  `urdf-pipeline run CONFIG --force` on one Panda parquet episode vs the same job written by hand
  g1_1m, g1_3m        the same on one G1 episode, all 29 joints (hand-written at 3M only with --hand-3m: ~11 GB today)
  demo                `urdf-pipeline run configs/demo.yaml --force` (900 frames) vs `python -c "import rerun"`
  dataset             the real G1 recording of ../shared, every episode lengthened 40x, split layout: --jobs 1,
                      --jobs 2, an up-to-date re-run (no --force) right after the --jobs 2 run, and the machine's
                      two-process ceiling (one pure-Python process alone, then two at once)

The hand-written job is benchmarks/hand_written.py (two-lens FK + collect(OBJECT_STORE) + write_rrd). The two ways of
a row run alternately, in ABBA order over --repeat rounds; the table shows ranges, medians and the ratios ours/hand of
each round. Inputs are generated into the work directory (a temporary one unless --workdir), outputs are deleted
after each row. Peak RSS is ru_maxrss of the child from os.wait4: the largest process of the command's tree (a
--jobs 2 run: the driver or a worker). Linux starts a child's ru_maxrss at its parent's, so this process imports
nothing heavy (inputs are made by bench_inputs.py in a child); its own peak is printed as the floor.
With --verify, each single-segment row's two outputs are compared (benchmarks/compare_rrd.py: same entities, same
transforms at every frame; slow above ~100k frames).
Usage: python benchmarks/bench_all.py [--repeat 5] [--only panda300k,demo,...] [--scale 1.0] [--workdir DIR] [--hand-3m]
       [--verify]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROWS = ["panda300k", "panda1m", "g1_1m", "g1_3m", "demo", "dataset"]
CEILING_LOOPS = 20_000_000  # about 2 s of pure-Python work on this machine's cores
CEILING_SCRIPT = f"n = 0\nfor i in range({CEILING_LOOPS}):\n    n += i * i\n"
GOALS = {"panda300k": 1.0, "panda1m": 0.8, "g1_1m": 0.8}  # ours/hand time ratio
G1_MEMORY_GOAL_MB = 600.0


@dataclass(frozen=True)
class Sample:
    """One process (tree) as measured from outside: wall seconds, peak RSS in MB (10^6 bytes), CPU seconds."""

    seconds: float
    peak_mb: float
    cpu: float


class Runner:
    """Starts commands in the work directory and measures each with os.wait4; a failure stops the benchmark."""

    def __init__(self, workdir: Path) -> None:
        self.workdir, self.count = workdir, 0
        cli = Path(sys.executable).parent / "urdf-pipeline"
        self.cli = [str(cli)] if cli.exists() else [sys.executable, "-m", "urdf_pipeline"]
        (workdir / "logs").mkdir(parents=True, exist_ok=True)

    def start(self, command: list[str], name: str) -> tuple[subprocess.Popen[bytes], Path]:
        self.count += 1
        log = self.workdir / "logs" / f"{self.count:03d}-{name}.log"
        with log.open("wb") as out:
            return subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, cwd=self.workdir), log

    def finish(self, process: subprocess.Popen[bytes], log: Path, started: float) -> Sample:
        _, status, usage = os.wait4(process.pid, 0)
        seconds = time.perf_counter() - started
        process.returncode = os.waitstatus_to_exitcode(status)
        if process.returncode != 0:
            tail = "\n".join(log.read_text(errors="replace").splitlines()[-30:])
            raise SystemExit(f"{' '.join(map(str, process.args))} exited with {process.returncode}; end of {log}:\n{tail}")  # type: ignore[arg-type]
        return Sample(seconds, usage.ru_maxrss * 1024 / 1e6, usage.ru_utime + usage.ru_stime)

    def measure(self, command: list[str], name: str) -> Sample:
        started = time.perf_counter()
        process, log = self.start(command, name)
        sample = self.finish(process, log, started)
        print(f"  {name}: {sample.seconds:.2f} s, {mb(sample.peak_mb)}", file=sys.stderr, flush=True)
        return sample

    def measure_pair(self, command: list[str], name: str) -> Sample:
        """Two copies at once: the wall time until both are done, the larger peak."""
        started = time.perf_counter()
        running = [self.start(command, f"{name}-{i}") for i in (1, 2)]
        samples = [self.finish(process, log, started) for process, log in running]
        sample = Sample(max(s.seconds for s in samples), max(s.peak_mb for s in samples), sum(s.cpu for s in samples))
        print(f"  {name}: {sample.seconds:.2f} s", file=sys.stderr, flush=True)
        return sample

    def ours(self, config: str, *extra: str) -> list[str]:
        return [*self.cli, "run", config, *extra]

    def hand(self, hand: dict) -> list[str]:
        ids = ["--application-id", hand["application_id"], "--recording-id", hand["recording_id"]]
        return [sys.executable, str(HERE / "hand_written.py"), hand["robot"], str(self.workdir), hand["parquet"], hand["output"], *ids]


# ---------------------------------------------------------------------------------------------------------------
# Formatting
# ---------------------------------------------------------------------------------------------------------------


def mb(value: float) -> str:
    return f"{value / 1000:.2f} GB" if value >= 1000 else f"{value:.0f} MB"


def spread(values: list[float], unit: str, digits: int = 2) -> str:
    """`1.70–1.90 s (median 1.80)`, or just `1.80 s` for one value."""
    if len(values) == 1:
        return f"{values[0]:.{digits}f}{unit}"
    return f"{min(values):.{digits}f}–{max(values):.{digits}f}{unit} (median {statistics.median(values):.{digits}f})"


def cell(samples: list[Sample]) -> str:
    return f"{spread([s.seconds for s in samples], ' s')}, {mb(max(s.peak_mb for s in samples))}"


def verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


# ---------------------------------------------------------------------------------------------------------------
# Rows
# ---------------------------------------------------------------------------------------------------------------


def alternate(runner: Runner, repeat: int, ways: dict[str, Callable[[], Sample]]) -> dict[str, list[Sample]]:
    """Every way once per round, in ABBA order, so that drift on a shared machine affects each alike."""
    results: dict[str, list[Sample]] = {name: [] for name in ways}
    for round_index in range(repeat):
        order = list(ways) if round_index % 2 == 0 else list(reversed(ways))
        for name in order:
            results[name].append(ways[name]())
    return results


def single_segment(runner: Runner, row: str, spec: dict, repeat: int, hand_too: bool) -> dict[str, list[Sample]]:
    ways: dict[str, Callable[[], Sample]] = {}
    if hand_too:
        ways["hand"] = lambda: runner.measure(runner.hand(spec["hand"]), f"{row}-hand")
    ways["ours"] = lambda: runner.measure(runner.ours(spec["config"], "--force"), f"{row}-ours")
    return alternate(runner, repeat, ways)


def demo(runner: Runner, spec: dict, repeat: int) -> dict[str, list[Sample]]:
    ways = {
        "hand": lambda: runner.measure([sys.executable, "-c", "import rerun"], "import-rerun"),
        "ours": lambda: runner.measure(runner.ours(spec["config"], "--force"), "demo-ours"),
    }
    return alternate(runner, repeat, ways)


def dataset(runner: Runner, spec: dict, repeat: int) -> dict[str, list[Sample]]:
    outputs = Path(spec["outputs"])
    rewritten: list[int] = []

    def stats() -> dict[str, int]:
        return {p.name: p.stat().st_mtime_ns for p in outputs.glob("*.rrd")}

    def jobs2_then_rerun() -> Sample:
        results["jobs2"].append(runner.measure(runner.ours(spec["config"], "--force", "--jobs", "2"), "dataset-jobs2"))
        before = stats()
        sample = runner.measure(runner.ours(spec["config"], "--jobs", "2"), "dataset-rerun")
        rewritten.append(sum(before.get(name) != mtime for name, mtime in stats().items()))
        return sample

    results: dict[str, list[Sample]] = {"jobs2": []}
    ways = {
        "jobs1": lambda: runner.measure(runner.ours(spec["config"], "--force", "--jobs", "1"), "dataset-jobs1"),
        "rerun": jobs2_then_rerun,
        "alone": lambda: runner.measure([sys.executable, "-c", CEILING_SCRIPT], "ceiling-one"),
        "pair": lambda: runner.measure_pair([sys.executable, "-c", CEILING_SCRIPT], "ceiling-two"),
    }
    results.update(alternate(runner, repeat, ways))
    if any(rewritten):
        print(f"warning: the up-to-date re-run rewrote {max(rewritten)} recordings", file=sys.stderr)
    return results


def table(made: dict, measured: dict[str, dict[str, list[Sample]]], skipped: dict[str, str]) -> list[str]:
    lines = ["| input | hand-written / reference | urdf-pipeline | ours / hand | goal |", "|---|---|---|---|---|"]
    labels = {"panda300k": "Panda, {} frames, parquet", "panda1m": "Panda, {} frames", "g1_1m": "G1 (29 joints), {} frames"}
    for row in ROWS:
        if row in skipped:
            lines.append(f"| {row} | skipped: {skipped[row]} | | | |")
        if row not in measured:
            continue
        spec, result = made[row], measured[row]
        ours = result.get("ours", [])
        if row in labels:
            hand = result["hand"]
            times = [o.seconds / h.seconds for o, h in zip(ours, hand, strict=True)]
            memory = [o.peak_mb / h.peak_mb for o, h in zip(ours, hand, strict=True)]
            goal = f"≤ {GOALS[row]}x time: {verdict(statistics.median(times) <= GOALS[row])}"
            if row == "g1_1m":
                goal += f"; ≤ {G1_MEMORY_GOAL_MB:.0f} MB: {verdict(max(o.peak_mb for o in ours) <= G1_MEMORY_GOAL_MB)}"
            ratio = f"time {spread(times, 'x')}, RSS {spread(memory, 'x')}"
            label = labels[row].format(f"{spec['frames']:,}")
            lines.append(f"| {label} | {cell(hand)} | {cell(ours)} | {ratio} | {goal} |")
        elif row == "g1_3m":
            peak = max(o.peak_mb for o in ours)
            hand_cell = cell(result["hand"]) if "hand" in result else "– (--hand-3m)"
            ratio, goal = "", f"≤ {G1_MEMORY_GOAL_MB:.0f} MB: {verdict(peak <= G1_MEMORY_GOAL_MB)}"
            if "hand" in result:
                ratio = f"time {spread([o.seconds / h.seconds for o, h in zip(ours, result['hand'], strict=True)], 'x')}; "
            if "g1_1m" in measured:
                growth = peak / max(o.peak_mb for o in measured["g1_1m"]["ours"])
                ratio += f"peak / G1 {made['g1_1m']['frames']:,}-frame peak {growth:.2f}x"
                goal += f"; ≤ 1.25x that peak: {verdict(growth <= 1.25)}"
            lines.append(f"| G1, {spec['frames']:,} frames | {hand_cell} | {cell(ours)} | {ratio} | {goal} |")
        elif row == "demo":
            extra = [o.seconds - h.seconds for o, h in zip(ours, result["hand"], strict=True)]
            goal = f"≤ `import rerun` + 0.5 s: {verdict(statistics.median(extra) <= 0.5)}"
            lines.append(
                f'| demo, {spec["frames"]} frames | `python -c "import rerun"`: {cell(result["hand"])} | {cell(ours)} | '
                f"+{spread(extra, ' s')} over `import rerun` | {goal} |"
            )
        elif row == "dataset":
            one, two, rerun, alone, pair = (result[k] for k in ("jobs1", "jobs2", "rerun", "alone", "pair"))
            speedup = [a.seconds / b.seconds for a, b in zip(one, two, strict=True)]
            ceiling = [2 * a.seconds / p.seconds for a, p in zip(alone, pair, strict=True)]
            share = [100 * s / c for s, c in zip(speedup, ceiling, strict=True)]
            rerun_share = [100 * r.seconds / t.seconds for r, t in zip(rerun, two, strict=True)]
            # --jobs 1 already runs on more than one core (Rerun's reader, lens and writer threads overlap): two jobs
            # can at best take its CPU seconds in half the wall time. The share of that bound says how much the pool
            # itself leaves on the table; the pure-Python ceiling assumes one job = one core.
            cores = [a.cpu / a.seconds for a in one]
            cpu_bound = [a.cpu / 2 for a in one]
            cpu_share = [100 * b / t.seconds for b, t in zip(cpu_bound, two, strict=True)]
            name = f"G1 dataset, {spec['episodes']} episodes, {spec['frames']:,} frames"
            lines += [
                f"| {name}, --jobs 1 | – | {cell(one)} | | |",
                f"| {name}, --jobs 2 | – | {cell(two)} | speed-up {spread(speedup, 'x')} = {spread(share, ' %', 0)} of the ceiling "
                f"| ≥ 85 % of the ceiling: {verdict(statistics.median(share) >= 85)} |",
                f"| CPU-time bound for --jobs 2 | --jobs 1 uses {spread(cores, ' cores')} | half of its CPU time: {spread(cpu_bound, ' s')} "
                f"| --jobs 2 at {spread(cpu_share, ' %', 0)} of this bound | |",
                f"| two-process ceiling (pure Python) | one process: {cell(alone)} | two at once: {cell(pair)} | ceiling {spread(ceiling, 'x')} | |",
                f"| up-to-date re-run (--jobs 2, no --force) | – | {cell(rerun)} | {spread(rerun_share, ' %', 1)} of the --jobs 2 run "
                f"| ≤ 5 %: {verdict(statistics.median(rerun_share) <= 5)} |",
            ]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3, help="rounds per row (default 3; 5 or more before drawing conclusions)")
    parser.add_argument("--only", default=",".join(ROWS), help=f"comma-separated rows, of {','.join(ROWS)}")
    parser.add_argument("--scale", type=float, default=1.0, help="multiply every frame count (the demo's stays 900), e.g. 0.01 to test")
    parser.add_argument("--workdir", type=Path, help="keep inputs (reused next time) and logs here (default: a temporary directory)")
    parser.add_argument("--hand-3m", action="store_true", help="also run the hand-written G1 3M job (about 11 GB of RAM today)")
    parser.add_argument("--verify", action="store_true", help="check that ours and the hand-written output hold the same transforms")
    args = parser.parse_args()
    rows = [row for row in args.only.split(",") if row]
    if unknown := sorted(set(rows) - set(ROWS)):
        parser.error(f"unknown rows {unknown}; choose from {ROWS}")
    rows = [row for row in ROWS if row in rows]
    temporary = None if args.workdir else tempfile.TemporaryDirectory(prefix="bench-all-")
    workdir = (args.workdir or Path(temporary.name)).resolve()  # type: ignore[union-attr]
    workdir.mkdir(parents=True, exist_ok=True)
    began, load = time.perf_counter(), os.getloadavg()
    try:
        print(f"bench_all: generating inputs in {workdir} ...", file=sys.stderr, flush=True)
        prepare = [sys.executable, str(HERE / "bench_inputs.py"), str(workdir), "--rows", ",".join(rows), "--scale", str(args.scale)]
        done = subprocess.run(prepare, stdout=subprocess.PIPE, text=True, check=True)
        made = json.loads(done.stdout.strip().splitlines()[-1])
        skipped = {row: spec["skipped"] for row, spec in made.items() if "skipped" in spec}
        for row, reason in skipped.items():
            print(f"bench_all: row {row} skipped: {reason}", file=sys.stderr)
        runner = Runner(workdir)
        # The package's bytecode, as a wheel install has it (`make` does this too): PYTHONDONTWRITEBYTECODE, set in
        # some CI images, would otherwise make every measured command compile the package again.
        subprocess.run(
            [sys.executable, "-m", "compileall", "-q", str(HERE.parent / "urdf_pipeline")], stdout=subprocess.DEVNULL, check=True
        )
        configs = [spec["config"] for row, spec in made.items() if row not in skipped]
        runner.measure([*runner.cli, "validate", *configs], "validate")  # also warms the file cache and .pyc files
        if "demo" in made:
            runner.measure(runner.ours(made["demo"]["config"], "--force"), "warm-up")
        prepared = time.perf_counter()
        measured: dict[str, dict[str, list[Sample]]] = {}
        verified: list[str] = []
        for row in rows:
            if row in skipped:
                continue
            print(f"bench_all: {row} ({made[row]['frames']:,} frames), {args.repeat} round(s)", file=sys.stderr, flush=True)
            if row == "demo":
                measured[row] = demo(runner, made[row], args.repeat)
            elif row == "dataset":
                measured[row] = dataset(runner, made[row], args.repeat)
            else:
                measured[row] = single_segment(runner, row, made[row], args.repeat, row != "g1_3m" or args.hand_3m)
                if args.verify and "hand" in measured[row]:
                    compare = [sys.executable, str(HERE / "compare_rrd.py"), made[row]["output"], made[row]["hand"]["output"]]
                    checked = subprocess.run(compare, stdout=subprocess.PIPE, text=True)
                    verified.append(f"verify {row}: {checked.stdout.strip() or f'compare_rrd.py exited with {checked.returncode}'}")
            shutil.rmtree(workdir / "out", ignore_errors=True)
        own_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6
        print()
        print(
            f"urdf-pipeline vs hand-written, whole processes: scale {args.scale:g}, {args.repeat} round(s) in ABBA order; "
            f"{os.cpu_count()} cores, load average {load[0]:.2f} before and {os.getloadavg()[0]:.2f} after; "
            f"peak RSS of the measuring process {mb(own_peak)} (the floor of every RSS figure)"
        )
        print()
        print("\n".join(table(made, measured, skipped) + ([""] if verified else []) + verified))
        print()
        logs = f"; logs in {workdir / 'logs'}" if args.workdir else ""
        print(f"inputs and validation {prepared - began:.0f} s, measurements {time.perf_counter() - prepared:.0f} s{logs}")
    finally:
        if temporary is not None:
            temporary.cleanup()


if __name__ == "__main__":
    main()

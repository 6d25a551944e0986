"""What `trails:` costs on bench_all.py's single-episode inputs: `urdf-pipeline run CONFIG --force` without and with
two trails, in ABBA order, each a whole process measured from outside (wall time, CPU time, peak RSS), and the size
of the recording it writes. Peak RSS is the figure that says whether memory grows with the segment: a trail keeps
one position per trail between blocks, so it must stay flat. CPU time is the steadier figure on a shared machine.

    .venv/bin/python benchmarks/bench_trails.py --repeat 3                        # panda1m
    .venv/bin/python benchmarks/bench_trails.py --only panda300k --scale 0.01 --repeat 1 --workdir /tmp/bench
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_all import HERE, Runner, Sample, alternate, mb, spread

ROWS = ["panda300k", "panda1m", "g1_1m"]
TRAILS = {  # two trails per robot: an end effector in the root frame as a line, another link in the robot's base as points
    "panda": "trails:\n  - {link: panda_hand, window: 200 rows}\n  - {link: panda_leftfinger, frame: panda_link0, style: points, window: 200 rows}\n",
    "g1": "trails:\n  - {link: left_ankle_roll_link, window: 200 rows}\n  - {link: right_ankle_roll_link, frame: pelvis, style: points, window: 200 rows}\n",
}


def with_trails(config: Path, row: str) -> Path:
    """The same config with two trails, beside it (its own manifest; the same output path)."""
    text = config.read_text()
    if "\ntrails:" in text:
        raise SystemExit(f"{config}: already has trails")
    variant = config.with_name(f"{config.stem}_trails.yaml")
    variant.write_text(text.rstrip("\n") + "\n" + TRAILS["g1" if row.startswith("g1") else "panda"])
    return variant


def measure_row(runner: Runner, row: str, spec: dict, repeat: int) -> str:
    """One table row: the config without and with trails, alternated; the recording's size after each."""
    off, on = Path(spec["config"]), with_trails(Path(spec["config"]), row)
    output = Path(spec["output"])
    sizes: dict[str, int] = {}

    def measure(config: Path, name: str) -> Sample:
        sample = runner.measure(runner.ours(str(config), "--force"), f"{row}-{name}")
        sizes[name] = output.stat().st_size
        return sample

    runner.measure([*runner.cli, "validate", str(off), str(on)], f"{row}-validate")  # warms the file cache
    results = alternate(runner, repeat, {"off": lambda: measure(off, "off"), "on": lambda: measure(on, "on")})
    cells = [
        f"{spread([s.seconds for s in results[w]], ' s')}, CPU {statistics.median(s.cpu for s in results[w]):.2f} s, {mb(max(s.peak_mb for s in results[w]))}"
        for w in ("off", "on")
    ]
    ratios = [
        statistics.median(getattr(s, f) for s in results["on"]) / statistics.median(getattr(s, f) for s in results["off"])
        for f in ("seconds", "cpu", "peak_mb")
    ]
    frames, size_off, size_on = f"{spec['frames']:,}", mb(sizes["off"] / 1e6), mb(sizes["on"] / 1e6)
    return f"| {row} ({frames} frames) | {cells[0]} | {cells[1]} | {ratios[0]:.2f} / {ratios[1]:.2f} / {ratios[2]:.2f} | {size_off} / {size_on} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3, help="rounds per row (default 3)")
    parser.add_argument("--only", default="panda1m", help=f"comma-separated rows, of {','.join(ROWS)}")
    parser.add_argument("--scale", type=float, default=1.0, help="multiply every frame count, e.g. 0.01 to test")
    parser.add_argument("--workdir", type=Path, help="keep inputs (reused next time) and logs here (default: a temporary directory)")
    args = parser.parse_args()
    rows = [row for row in args.only.split(",") if row]
    if unknown := sorted(set(rows) - set(ROWS)):
        parser.error(f"unknown rows {unknown}; choose from {ROWS}")
    temporary = None if args.workdir else tempfile.TemporaryDirectory(prefix="bench-trails-")
    workdir = (args.workdir or Path(temporary.name)).resolve()  # type: ignore[union-attr]
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        prepare = [sys.executable, str(HERE / "bench_inputs.py"), str(workdir), "--rows", ",".join(rows), "--scale", str(args.scale)]
        made = json.loads(subprocess.run(prepare, stdout=subprocess.PIPE, text=True, check=True).stdout.strip().splitlines()[-1])
        runner = Runner(workdir)
        lines = [
            "| row | without trails: wall, CPU (median), peak RSS | with two trails | with / without: wall / CPU / peak RSS (medians) | recording without / with |",
            "| --- | --- | --- | --- | --- |",
        ]
        lines += [measure_row(runner, row, made[row], args.repeat) for row in rows]
        print("\n".join(lines))
    finally:
        if temporary is not None:
            temporary.cleanup()


if __name__ == "__main__":
    main()

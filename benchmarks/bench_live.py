"""Benchmark: live views (issue 25). A 29-joint humanoid (the G1 of example-robot-data, every joint driven) at 1 kHz.

Part 1, the Python API in a control loop. Each variant is a process of its own, alternated `--repeat` times:
  live        `urdf_pipeline.live(config, save=...)`, `view.push(q, time=t)` once per 1 ms tick
  live_batch  the same loop, `view.push_batch(rows, times)` every 100 ticks
  hand        the hand-written way of Rerun's own animated_urdf example: the URDF logged once, then each tick, per
              joint, `rec.log(entity, joint.compute_transform(q_j))` after `rec.set_time(...)` (no mapping, units or
              limits at all: what the live view does besides is extra work it still beats)
Reported per variant (medians): microseconds a push costs the loop (the call's own time), CPU microseconds per sample
of the whole process (every thread: Rerun's, our flusher), and the share of 1 ms ticks that were late.

Part 2, `urdf-pipeline live CONFIG --from ws://... --save` against a real Foxglove WebSocket server (foxglove-sdk,
a child process) publishing JointState at 100 Hz and 1 kHz: the command's own latency line (from a sample's arrival to
it being sent, median and 99th percentile) and its CPU seconds, beside a hand-written client (the same feed, then
`rec.log` per joint of `compute_transform`) measured the same way.

Usage: python benchmarks/bench_live.py [--samples 5000] [--repeat 3] [--part api|stream|all] [--workdir DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.bench_live_stream import G1, g1_joints  # noqa: E402  shared with part 2, imported one way


def prepare(workdir: Path) -> Path:
    from urdf_pipeline.examples import prepare as prepare_examples

    prepare_examples(workdir, frames=10)
    names = g1_joints(workdir / G1)
    spec = {
        "version": 1,
        "sources": {"g1": {"mcap": "live.mcap", "topic": "/joint_states", "names": names}},
        "robots": {
            "g1": {
                "urdf": G1,
                "package_paths": {"example-robot-data": "robots/share/example-robot-data"},
                "joints": {"source": "g1", "unit": "rad", "map": {n: n for n in names}},
            }
        },
        "output": {"path": "out/{segment}.rrd", "application_id": "g1_live", "segment": "g1"},
    }
    config = workdir / "g1_live.yaml"
    config.write_text(yaml.safe_dump(spec, sort_keys=False))
    return config


def motion(names: list[str], samples: int) -> object:
    import numpy as np

    t = np.arange(samples)[:, None] / 1000.0
    return 0.075 + 0.12 * np.sin(2 * np.pi * 0.5 * t + np.arange(len(names))[None, :])  # within every G1 joint's limits


def loop(variant: str, config: Path, samples: int, out: Path) -> dict[str, float]:
    """One variant's 1 kHz loop in this process; its figures."""
    import numpy as np

    names = g1_joints(config.parent / G1)
    q = motion(names, samples)
    assert isinstance(q, np.ndarray)
    start_s = time.time()
    push = make_push(variant, config, names, out)
    late = 0
    spent = 0.0
    cpu = time.process_time()
    began = time.perf_counter()
    for k in range(samples):
        called = time.perf_counter()
        push(k, q, start_s + k / 1000)
        spent += time.perf_counter() - called
        deadline = began + (k + 1) / 1000
        late += time.perf_counter() > deadline
        while time.perf_counter() < deadline:
            pass
    push(-1, q, 0.0)  # close
    busy = (time.process_time() - cpu) - (time.perf_counter() - began - spent)  # the loop's busy wait left out
    return {"push_us": spent / samples * 1e6, "cpu_us_per_sample": busy / samples * 1e6, "late_share": late / samples}


def make_push(variant: str, config: Path, names: list[str], out: Path):  # a closure per variant
    import numpy as np
    import rerun as rr

    if variant in ("live", "live_batch"):
        import urdf_pipeline

        view = urdf_pipeline.live(config, save=out)
        pending: list[int] = []

        def push_live(k: int, q: np.ndarray, t: float) -> None:
            if k < 0:
                if pending:
                    view.push_batch(q[pending], np.array(pending) / 1000.0)
                view.close()
            elif variant == "live":
                view.push(q[k], time=t)
            else:
                pending.append(k)
                if len(pending) == 100:
                    view.push_batch(q[pending], t - (k - np.array(pending)) / 1000.0)
                    pending.clear()

        return push_live
    from rerun.urdf import UrdfTree

    rec = rr.RecordingStream("g1_hand")
    rec.save(out)
    urdf = config.parent / G1
    rec.log_file_from_path(urdf, static=True)
    tree = UrdfTree.from_file_path(urdf)
    joints = [tree.get_joint_by_name(n) for n in names]

    def push_hand(k: int, q: np.ndarray, t: float) -> None:
        if k < 0:
            rec.flush()
            rec.disconnect()
            return
        rec.set_time("time", timestamp=t)
        for joint, value in zip(joints, q[k], strict=True):
            rec.log("transforms", joint.compute_transform(float(value)))  # type: ignore[union-attr]

    return push_hand


def run_variant(variant: str, config: Path, samples: int, workdir: Path) -> dict[str, float]:
    out = workdir / f"{variant}.rrd"
    command = [sys.executable, __file__, "--child", variant, "--config", str(config), "--samples", str(samples), "--out", str(out)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise SystemExit(f"{variant} failed:\n{done.stderr[-3000:]}")
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    figures["command_s"] = wall
    figures["command_cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return figures


def part_api(config: Path, samples: int, repeat: int, workdir: Path) -> None:
    variants = ("live", "live_batch", "hand")
    results: dict[str, list[dict[str, float]]] = {v: [] for v in variants}
    for _ in range(repeat):
        for variant in variants:
            results[variant].append(run_variant(variant, config, samples, workdir))
    print(f"\n1 kHz loop, 29 joints, {samples} samples, medians of {repeat}:")
    print(f"{'variant':<11} {'push µs':>9} {'CPU µs/sample':>14} {'late ticks':>11} {'command s':>10} {'command CPU s':>14}")
    for variant in variants:
        rows = results[variant]

        def median(key: str, rows: list[dict[str, float]] = rows) -> float:
            return statistics.median(r[key] for r in rows)

        print(
            f"{variant:<11} {median('push_us'):>9.1f} {median('cpu_us_per_sample'):>14.1f} {median('late_share'):>10.1%} "
            f"{median('command_s'):>10.2f} {median('command_cpu_s'):>14.2f}"
        )
    hand = statistics.median(r["cpu_us_per_sample"] for r in results["hand"])
    ours = statistics.median(r["cpu_us_per_sample"] for r in results["live"])
    print(f"CPU per sample, hand-written / live: {hand / ours:.1f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=5000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--part", choices=("api", "stream", "all"), default="all")
    parser.add_argument("--workdir", type=Path)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--config", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(loop(args.child, args.config, args.samples, args.out)))
        return
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="bench-live-"))
    os.environ["URDF_PIPELINE_ALLOW_PATHS"] = str(workdir)
    config = prepare(workdir)
    if args.part in ("api", "all"):
        part_api(config, args.samples, args.repeat, workdir)
    if args.part in ("stream", "all"):
        from benchmarks.bench_live_stream import part_stream

        part_stream(config, args.repeat, workdir)


if __name__ == "__main__":
    main()

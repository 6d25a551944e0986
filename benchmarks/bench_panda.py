"""Benchmark: config-driven pipeline vs. the same pipeline hand-written with Rerun's lens API.

One Franka Panda, one parquet episode of N frames (units of configs/demo.yaml: degrees, j2 negated,
j3 offset 0.1 rad, finger in mm). The parent process generates the inputs once, then runs every
variant in its own child process (this script re-invoked with --variant) so each child's peak RSS
is its own (VmHWM). Timed: from compile/URDF load to the written .rrd; interpreter start and imports are not.
Usage: python benchmarks/bench_panda.py [--frames 1000000] [--repeat 1] [--workdir DIR] [--verify]
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
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DEMO_CONFIG = REPO / "configs" / "demo.yaml"
APPLICATION_ID, RECORDING_ID = "panda_demo", "episode_000"  # as in configs/demo.yaml
VARIANTS = {"config": "config-driven (urdf_pipeline)", "hand": "hand-written (Rerun API)"}


# ---------------------------------------------------------------------------------------------
# Inputs (parent process)
# ---------------------------------------------------------------------------------------------


def prepare_inputs(workdir: Path, frames: int) -> Path:
    from urdf_pipeline.examples import panda_raw_values, prepare, write_joint_parquet
    from urdf_pipeline.urdf.model import read_urdf

    prepare(workdir, frames=10)  # robots/panda.urdf, robots/share/example-robot-data, small example data
    _, panda = read_urdf(workdir / "robots" / "panda.urdf")
    write_joint_parquet(workdir / "data" / "episode_000.parquet", panda_raw_values(frames, panda))
    config = workdir / "demo.yaml"
    shutil.copyfile(DEMO_CONFIG, config)
    return config


# ---------------------------------------------------------------------------------------------
# Variant (a): exactly what `urdf-pipeline run CONFIG` does
# ---------------------------------------------------------------------------------------------


def run_config(workdir: Path) -> Path:
    from urdf_pipeline.compile.compiler import compile_config
    from urdf_pipeline.execute.segment import execute

    return execute(compile_config(workdir / "demo.yaml")).output


# ---------------------------------------------------------------------------------------------
# Variant (b): the same pipeline written directly against the Rerun 0.41 API
# ---------------------------------------------------------------------------------------------


def run_hand(workdir: Path) -> Path:
    import functools

    import numpy as np
    import pyarrow as pa
    import rerun as rr
    from rerun.chunk import Chunk, DeriveLens, IndexColumn, LazyChunkStream, OptimizationProfile, Selector
    from rerun.experimental import ParquetReader
    from rerun.urdf import UrdfTree

    joints = [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1", "panda_finger_joint2"]
    # raw columns j1..j7 (deg), finger (mm) -> URDF units: j2 negated, j3 + 0.1 rad
    scale = np.array([np.pi / 180] * 7 + [1e-3])
    scale[1] = -scale[1]
    offset = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0])

    os.environ["ROS_PACKAGE_PATH"] = str(workdir / "robots" / "share")  # resolves package://example-robot-data/
    tree = UrdfTree.from_file_path(workdir / "robots" / "panda.urdf", "arm", static_transform_entity_path="/arm/tf_static")

    @functools.cache
    def joint_names(rows: int) -> pa.Array:
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * len(joints))
        return pa.ListArray.from_arrays(offsets, pa.array(joints * rows, pa.string()))

    def joint_transforms(vectors: pa.Array) -> pa.Array:  # one joint vector per row
        rows = len(vectors)
        raw = vectors.flatten().to_numpy(zero_copy_only=False).reshape(rows, 8).astype(np.float64)
        q = raw * scale + offset
        q = np.concatenate([q, q[:, 7:8]], axis=1)  # mimic: panda_finger_joint2 = panda_finger_joint1
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * len(joints))
        values = pa.ListArray.from_arrays(offsets, pa.array(q.reshape(-1)))  # fresh float64 array per call
        return tree.compute_joint_transform_batches(joint_names(rows), values)

    compute = DeriveLens("observation.state", output_entity="/arm/joint_transform_batches").to_component(
        "JointTransformBatch", Selector(".").pipe(joint_transforms)
    )
    scatter = (
        DeriveLens("JointTransformBatch", output_entity="/arm/joint_transforms", scatter=True)
        .to_component(rr.Transform3D.descriptor_translation(), Selector(".[].translation"))
        .to_component(rr.Transform3D.descriptor_quaternion(), Selector(".[].quaternion"))
        .to_component(rr.Transform3D.descriptor_parent_frame(), Selector(".[].parent_frame"))
        .to_component(rr.Transform3D.descriptor_child_frame(), Selector(".[].child_frame"))
    )
    fk = (
        ParquetReader(workdir / "data" / "episode_000.parquet")
        .stream(index_columns=[IndexColumn.sequence("frame_index")], column_grouping="individual")
        .lenses(compute)
        .lenses(scatter)
    )
    model = tree.stream().drop(content="/arm/panda/collision_geometries/**")
    calibration = Chunk.from_columns(
        "/calibration",
        indexes=[],
        columns=rr.Transform3D.columns(
            translation=[[0.0, 0.0, 0.5]], quaternion=[[0.0, 0.0, 0.0, 1.0]], parent_frame=["world"], child_frame=["panda_link0"]
        ),
    )
    store = LazyChunkStream.merge(model, fk, LazyChunkStream.from_iter([calibration])).collect(optimize=OptimizationProfile.OBJECT_STORE)
    output = workdir / "out" / "hand_episode_000.rrd"
    output.parent.mkdir(parents=True, exist_ok=True)
    store.write_rrd(output, application_id=APPLICATION_ID, recording_id=RECORDING_ID)
    return output


# ---------------------------------------------------------------------------------------------
# Child process: run one variant, report seconds and peak RSS as JSON on the last stdout line
# ---------------------------------------------------------------------------------------------


def peak_rss_kib() -> int:
    """This process's own peak RSS. VmHWM, not ru_maxrss: Linux carries ru_maxrss over execve from the
    forked parent's memory, so a child of a big parent would report at least the parent's size."""
    try:
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("VmHWM:"))
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS


def child(variant: str, workdir: Path) -> None:
    import numpy  # noqa: F401  (imports are not timed)
    import pyarrow  # noqa: F401
    import rerun  # noqa: F401
    import rerun.chunk  # noqa: F401
    import rerun.urdf  # noqa: F401

    import urdf_pipeline.compile.compiler  # noqa: F401
    import urdf_pipeline.execute.segment  # noqa: F401

    baseline_kib = peak_rss_kib()
    before = resource.getrusage(resource.RUSAGE_SELF)
    cpu_before = before.ru_utime + before.ru_stime
    started = time.perf_counter()
    output = (run_config if variant == "config" else run_hand)(workdir)
    seconds = time.perf_counter() - started
    peak_kib = peak_rss_kib()
    usage = resource.getrusage(resource.RUSAGE_SELF)
    print(
        json.dumps(
            {
                "seconds": seconds,
                "cpu": usage.ru_utime + usage.ru_stime - cpu_before,
                "peak_kib": peak_kib,
                "baseline_kib": baseline_kib,
                "output": str(output),
                "bytes": output.stat().st_size,
            }
        )
    )


def run_child(variant: str, workdir: Path) -> dict:
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--variant", variant, "--workdir", str(workdir)],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        sys.stderr.write(done.stderr)
        raise SystemExit(f"variant {variant} failed with exit code {done.returncode}")
    return json.loads(done.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------------------------
# Optional check that both outputs hold the same transforms and the same entities
# ---------------------------------------------------------------------------------------------


def transform_tables(path: Path) -> tuple[dict, set]:
    import numpy as np
    import pyarrow.compute as pc
    from rerun.chunk import RrdReader

    parts: dict[str, list] = {}
    layout: set = set()
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        layout.add((chunk.entity_path, chunk.is_static, tuple(sorted(n for n in batch.schema.names if ":" in n))))
        if "Transform3D:child_frame" not in batch.schema.names:
            continue
        flat = {
            n: pc.list_flatten(batch.column(n))
            for n in ("Transform3D:translation", "Transform3D:quaternion", "Transform3D:parent_frame", "Transform3D:child_frame")
        }
        frame = batch.column("frame_index").to_numpy() if "frame_index" in batch.schema.names else np.full(batch.num_rows, -1)
        parts.setdefault(chunk.entity_path, []).append(
            (
                frame,
                np.asarray(flat["Transform3D:child_frame"].to_pylist()),
                np.asarray(flat["Transform3D:parent_frame"].to_pylist()),
                pc.list_flatten(flat["Transform3D:translation"]).to_numpy().reshape(-1, 3),
                pc.list_flatten(flat["Transform3D:quaternion"]).to_numpy().reshape(-1, 4),
            )
        )
    tables = {}
    for entity, chunks in parts.items():
        frame, child, parent, translation, quaternion = (np.concatenate(c) for c in zip(*chunks, strict=True))
        order = np.lexsort((child, frame))
        tables[entity] = (frame[order], child[order], parent[order], translation[order], quaternion[order])
    return tables, layout


def verify(a: Path, b: Path) -> str:
    import numpy as np

    ta, la = transform_tables(a)
    tb, lb = transform_tables(b)
    entities = lambda layout: {(e, s, c) for e, s, c in layout if not e.startswith("/__")}  # noqa: E731
    if {e for e, _, _ in entities(la)} != {e for e, _, _ in entities(lb)}:
        return f"DIFFERENT entities: {sorted({e for e, _, _ in entities(la)} ^ {e for e, _, _ in entities(lb)})}"
    if set(ta) != set(tb):
        return f"DIFFERENT transform entities: {sorted(ta)} vs {sorted(tb)}"
    worst = 0.0
    for entity in ta:
        (fa, ca, pa_, xa, qa), (fb, cb, pb, xb, qb) = ta[entity], tb[entity]
        if not (np.array_equal(fa, fb) and np.array_equal(ca, cb) and np.array_equal(pa_, pb)):
            return f"DIFFERENT frames/edges in {entity}"
        worst = max(worst, float(np.abs(xa - xb).max(initial=0)), float(np.abs(qa - qb).max(initial=0)))
    rows = {e: len(t[0]) for e, t in ta.items()}
    return f"same entities and transforms (max abs difference {worst:.3g}); transform rows {rows}"


# ---------------------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--workdir", type=Path, help="where inputs and outputs go (default: a temporary directory, removed afterwards)")
    parser.add_argument("--verify", action="store_true", help="also check that both .rrd files hold the same transforms (slow for big N)")
    parser.add_argument("--variant", choices=sorted(VARIANTS), help=argparse.SUPPRESS)
    args = parser.parse_args()

    if args.variant:
        child(args.variant, args.workdir.resolve())
        return

    temporary = None if args.workdir else tempfile.TemporaryDirectory(prefix="bench-panda-")
    workdir = (args.workdir or Path(temporary.name)).resolve()  # type: ignore[union-attr]
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        started = time.perf_counter()
        prepare_inputs(workdir, args.frames)
        print(f"inputs: {args.frames:,} frames in {workdir} ({time.perf_counter() - started:.1f} s)", flush=True)
        results: dict[str, list[dict]] = {v: [] for v in VARIANTS}
        for round_ in range(args.repeat):
            for variant in list(VARIANTS)[:: 1 if round_ % 2 == 0 else -1]:  # ABBA order: drift affects both alike
                results[variant].append(run_child(variant, workdir))
        print()
        print(f"{'variant':32} {'median s':>9} {'frames/s':>10} {'CPU s':>7} {'peak RSS MiB':>13} {'.rrd MiB':>9}   wall s of each run")
        summary = {}
        for variant, runs in results.items():
            wall = statistics.median(r["seconds"] for r in runs)
            cpu = statistics.median(r["cpu"] for r in runs)
            peak = max(r["peak_kib"] for r in runs) / 1024
            size = runs[-1]["bytes"] / 2**20
            summary[variant] = (wall, cpu, peak)
            runs_text = ", ".join(f"{r['seconds']:.2f}" for r in runs)
            print(f"{VARIANTS[variant]:32} {wall:9.2f} {args.frames / wall:10,.0f} {cpu:7.2f} {peak:13.0f} {size:9.1f}   {runs_text}")
        (wa, ca, pa_), (wb, cb, pb) = summary["config"], summary["hand"]
        print()
        print(f"ratio config-driven / hand-written: time {wa / wb:.3f}, CPU time {ca / cb:.3f}, peak RSS {pa_ / pb:.3f}")
        baseline = max(r["baseline_kib"] for runs in results.values() for r in runs) / 1024
        print(
            f"(peak RSS after imports, before work: ~{baseline:.0f} MiB; .rrd bytes: "
            + ", ".join(f"{v} {results[v][-1]['bytes']:,}" for v in VARIANTS)
            + ")"
        )
        if args.verify:
            print("verify:", verify(Path(results["config"][-1]["output"]), Path(results["hand"][-1]["output"])))
    finally:
        if temporary is not None:
            temporary.cleanup()


if __name__ == "__main__":
    main()

"""The benchmarks' reference: the pipeline written by hand against the Rerun 0.41 API, as Rerun's `rerun-urdf`
guidance does it (two-lens FK on a parquet stream, the URDF model, `collect(OptimizationProfile.OBJECT_STORE)`,
`write_rrd`). Run as a whole script in its own process, so its time and memory include interpreter start and imports,
as `urdf-pipeline run` is measured.

Usage: python benchmarks/hand_written.py panda|g1 WORKDIR PARQUET OUTPUT --application-id ID --recording-id ID
WORKDIR holds robots/ as `python -m urdf_pipeline.examples WORKDIR` makes it.
"""

from __future__ import annotations

import argparse
import functools
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk, DeriveLens, IndexColumn, LazyChunkStream, OptimizationProfile, Selector
from rerun.experimental import ParquetReader
from rerun.urdf import UrdfTree

PANDA_JOINTS = [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1", "panda_finger_joint2"]
G1_JOINTS = [  # the 29 actuated joints of g1_29dof_rev_1_0.urdf, in file order (the parquet's column order)
    *(
        f"{side}_{joint}_joint"
        for side in ("left", "right")
        for joint in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")
    ),
    "waist_yaw_joint",
    "waist_roll_joint",
    "waist_pitch_joint",
    *(
        f"{side}_{joint}_joint"
        for side in ("left", "right")
        for joint in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw")
    ),
]
G1_URDF = "robots/share/example-robot-data/robots/g1_description/urdf/g1_29dof_rev_1_0.urdf"


def panda_values(raw: np.ndarray) -> np.ndarray:
    """configs/demo.yaml's corrections: j1..j7 in degrees, j2 negated, j3 + 0.1 rad, finger in mm; the mimic finger."""
    scale = np.array([np.pi / 180] * 7 + [1e-3])
    scale[1] = -scale[1]
    offset = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0])
    q = raw * scale + offset
    return np.concatenate([q, q[:, 7:8]], axis=1)  # mimic: panda_finger_joint2 = panda_finger_joint1


def fk_stream(
    tree: UrdfTree, key: str, parquet: Path, joints: list[str], width: int, convert: Callable[[np.ndarray], np.ndarray]
) -> LazyChunkStream:
    """observation.state (one joint vector per row) -> JointTransformBatch -> one Transform3D row per joint."""

    @functools.cache
    def joint_names(rows: int) -> pa.Array:
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * len(joints))
        return pa.ListArray.from_arrays(offsets, pa.array(joints * rows, pa.string()))

    def joint_transforms(vectors: pa.Array) -> pa.Array:
        rows = len(vectors)
        q = convert(vectors.flatten().to_numpy(zero_copy_only=False).reshape(rows, width).astype(np.float64))
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * len(joints))
        values = pa.ListArray.from_arrays(offsets, pa.array(q.reshape(-1)))  # fresh float64 array per call
        return tree.compute_joint_transform_batches(joint_names(rows), values)

    compute = DeriveLens("observation.state", output_entity=f"/{key}/joint_transform_batches").to_component(
        "JointTransformBatch", Selector(".").pipe(joint_transforms)
    )
    scatter = (
        DeriveLens("JointTransformBatch", output_entity=f"/{key}/joint_transforms", scatter=True)
        .to_component(rr.Transform3D.descriptor_translation(), Selector(".[].translation"))
        .to_component(rr.Transform3D.descriptor_quaternion(), Selector(".[].quaternion"))
        .to_component(rr.Transform3D.descriptor_parent_frame(), Selector(".[].parent_frame"))
        .to_component(rr.Transform3D.descriptor_child_frame(), Selector(".[].child_frame"))
    )
    return (
        ParquetReader(parquet)
        .stream(index_columns=[IndexColumn.sequence("frame_index")], column_grouping="individual")
        .lenses(compute)
        .lenses(scatter)
    )


def run(robot: str, workdir: Path, parquet: Path, output: Path, application_id: str, recording_id: str) -> None:
    os.environ["ROS_PACKAGE_PATH"] = str(workdir / "robots" / "share")  # resolves package://example-robot-data/
    streams: list[LazyChunkStream] = []
    if robot == "panda":  # configs/demo.yaml: robot key arm, a calibration edge world -> panda_link0
        tree = UrdfTree.from_file_path(workdir / "robots" / "panda.urdf", "arm", static_transform_entity_path="/arm/tf_static")
        streams.append(tree.stream().drop(content="/arm/panda/collision_geometries/**"))
        streams.append(fk_stream(tree, "arm", parquet, PANDA_JOINTS, 8, panda_values))
        calibration = Chunk.from_columns(
            "/calibration",
            indexes=[],
            columns=rr.Transform3D.columns(
                translation=[[0.0, 0.0, 0.5]], quaternion=[[0.0, 0.0, 0.0, 1.0]], parent_frame=["world"], child_frame=["panda_link0"]
            ),
        )
        streams.append(LazyChunkStream.from_iter([calibration]))
    else:  # the G1 config of bench_inputs.py: robot key g1, all 29 joints in radians, no edges
        tree = UrdfTree.from_file_path(workdir / G1_URDF, "g1", static_transform_entity_path="/g1/tf_static")
        streams.append(tree.stream().drop(content="/g1/g1_29dof_rev_1_0/collision_geometries/**"))
        streams.append(fk_stream(tree, "g1", parquet, G1_JOINTS, len(G1_JOINTS), lambda q: q))
    store = LazyChunkStream.merge(*streams).collect(optimize=OptimizationProfile.OBJECT_STORE)
    output.parent.mkdir(parents=True, exist_ok=True)
    store.write_rrd(output, application_id=application_id, recording_id=recording_id)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("robot", choices=["panda", "g1"])
    parser.add_argument("workdir", type=Path)
    parser.add_argument("parquet", type=Path)
    parser.add_argument("output", type=Path)
    parser.add_argument("--application-id", required=True)
    parser.add_argument("--recording-id", required=True)
    args = parser.parse_args()
    run(args.robot, args.workdir.resolve(), args.parquet, args.output, args.application_id, args.recording_id)


if __name__ == "__main__":
    main()

"""A plan drawn without joint values: each robot at its rest pose (`rest_values`), with its calibration frames, as chunks.

The pose is written as the recordings write the FK (one temporal Transform3D per moving joint, on the `rest_pose`
timeline), so the viewer draws a recording like the ones `run` writes, minus the data. Temporal edges (a moving base)
are drawn as the identity; the calibration edges' frames (and the root) carry small axes, so a moved mount shows.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from ..plan import Plan, RobotPlan
from .frames import Timeline

if TYPE_CHECKING:
    from rerun.chunk import Chunk
    from rerun.urdf import UrdfTree

REST_POSE = Timeline("rest_pose", "sequence")
AXES_ENTITY = "/__urdf_pipeline_frames"
AXIS_LENGTH = 0.1  # metres

JointValues = Mapping[str, Mapping[str, float]]  # robot key -> URDF joint -> value (URDF units)


def rest_values(plan: Plan) -> dict[str, dict[str, float]]:
    """Each robot's rest pose: holds, zeros clamped into the limits (a Panda's fourth joint has no zero), mimics from
    their drivers."""
    poses: dict[str, dict[str, float]] = {}
    for robot in plan.robots:
        values: dict[str, float] = {}
        for channel in robot.channels:
            low = channel.lower if channel.lower is not None else -np.inf
            high = channel.upper if channel.upper is not None else np.inf
            values[channel.joint] = float(np.clip(0.0, low, high))
        values.update({hold.joint: hold.value for hold in robot.holds})
        for mimic in robot.mimics:  # ordered: a driver comes before its mimic
            values[mimic.joint] = values.get(mimic.driver, 0.0) * mimic.multiplier + mimic.offset
        poses[robot.key] = values
    return poses


def shared_values(old: Plan, new: Plan) -> dict[str, dict[str, float]]:
    """One set of joint values for two plans (diff): the new plan's rest pose, the old one's for joints only it has."""
    poses = rest_values(old)
    for key, values in rest_values(new).items():
        poses.setdefault(key, {}).update(values)
    return poses


def scene_chunks(plan: Plan, values: JointValues) -> list[Chunk]:
    """The model of every robot at `values` (joints it lacks are left at the model's rest pose), the calibration
    edges and their frames' axes."""
    import rerun as rr
    from rerun.chunk import Chunk

    from ..execute import cached_tree, calibration_stream, robot_model_stream

    chunks: list[Chunk] = []
    for robot in plan.robots:
        tree = cached_tree(robot)  # as a run loads it
        chunks += robot_model_stream(robot, tree).to_chunks()  # meshes and every joint's static edge
        moving = {*(c.joint for c in robot.channels), *(h.joint for h in robot.holds), *(m.joint for m in robot.mimics)}
        own = {joint: value for joint, value in values.get(robot.key, {}).items() if joint in moving}
        if own:
            chunks.append(_pose_chunk(robot, tree, own))
    chunks += calibration_stream(plan.edges).to_chunks()
    for edge in plan.temporal_edges:
        identity = rr.Transform3D.columns(
            translation=[(0.0, 0.0, 0.0)], quaternion=[(0.0, 0.0, 0.0, 1.0)], parent_frame=[edge.parent], child_frame=[edge.child]
        )
        chunks.append(Chunk.from_columns(edge.entity, indexes=[rr.TimeColumn(REST_POSE.name, sequence=[0])], columns=identity))
    frames = sorted({plan.root_frame, *(e.child for e in plan.edges), *(e.child for e in plan.temporal_edges)})
    for index, frame in enumerate(frames):
        axes = [*rr.CoordinateFrame.columns(frame=[frame]), *rr.TransformAxes3D.columns(axis_length=[AXIS_LENGTH])]
        chunks.append(Chunk.from_columns(f"{AXES_ENTITY}/{index}", indexes=[], columns=axes))
    return chunks


def _pose_chunk(robot: RobotPlan, tree: UrdfTree, values: Mapping[str, float]) -> Chunk:
    """The joints' transforms at `values`, by Rerun's own URDF kinematics, at 0 on the rest_pose timeline."""
    import rerun as rr
    from rerun.chunk import Chunk

    names = sorted(values)
    batch = tree.compute_joint_transform_batches(
        pa.array([names], pa.list_(pa.string())), pa.array([[values[n] for n in names]], pa.list_(pa.float64()))
    )
    transforms = batch.flatten()
    columns = rr.Transform3D.columns(
        translation=np.asarray(transforms.field("translation").to_pylist(), dtype=np.float64),
        quaternion=np.asarray(transforms.field("quaternion").to_pylist(), dtype=np.float64),
        parent_frame=transforms.field("parent_frame").to_pylist(),
        child_frame=transforms.field("child_frame").to_pylist(),
    )
    return Chunk.from_columns(robot.fk_entity, indexes=[rr.TimeColumn(REST_POSE.name, sequence=[0] * len(names))], columns=columns)

"""Forward kinematics as arrays, for analysis (`urdf_pipeline.forward_kinematics`): every link's pose in its robot's
root frame at every row of a segment, from the same values and joint transforms a run writes.

The source is read as a run reads it (streamed, in time order, the same corrections and checks: a value past its
limits or NaN raises as `run` would); each block's joint transforms come from the closed form of `joint_fk.py`, in
float64, and are composed down the URDF tree with numpy, one step per link over all rows. Fixed joints take their
URDF origin, as do floating and planar joints (what Rerun's model logs for them). The result holds every link at
every row: 56 bytes per link and row, so it grows with the segment (unlike a run).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import Problems
from ..plan import RecordingPlan, RobotPlan
from ..sources import JointValueMapper, module_for, raw_matrix, with_sorting_retry
from .joint_fk import ClosedFormJointTransforms, multiply_quaternions, quaternion_from_rpy, rotate, rotation_matrices
from .limits_report import check_joint_statistics
from .model_stream import cached_tree
from .remote_inputs import local_inputs

if TYPE_CHECKING:
    from rerun.urdf import UrdfJoint, UrdfTree


@dataclass(frozen=True)
class RobotKinematics:
    """One robot's link poses over a segment, in its root link's frame (URDF joints only; calibration edges are in
    the plan's `edges`). Rows are in time order; `times` holds each of the source's timelines at every row. A row
    the robot's NaN policy leaves out (`joints.nan: drop_row`) has NaN poses, where a run logs no transform."""

    robot: str
    root: str  # the root link's frame (with the robot's frame prefix)
    links: tuple[str, ...]  # frame names, the first axis of the arrays
    times: dict[str, np.ndarray]  # timeline -> int64 per row (sequence numbers, or nanoseconds)
    translations: np.ndarray  # links x rows x 3, metres
    quaternions: np.ndarray  # links x rows x 4, (x, y, z, w)

    def matrices(self) -> np.ndarray:
        """links x rows x 4 x 4 homogeneous transforms (root from link)."""
        matrices = np.zeros((*self.translations.shape[:2], 4, 4))
        matrices[..., :3, :3] = rotation_matrices(self.quaternions)
        matrices[..., :3, 3] = self.translations
        matrices[..., 3, 3] = 1.0
        return matrices

    def pose(self, link: str) -> tuple[np.ndarray, np.ndarray]:
        """(rows x 3 translations, rows x 4 quaternions) of one link, by frame name."""
        index = self.links.index(link)
        return self.translations[index], self.quaternions[index]


def segment_kinematics(plan: RecordingPlan) -> dict[str, RobotKinematics]:
    """Every robot of one segment's plan (`Plan.for_segment`), by robot key."""
    from ..errors import UserError

    result: dict[str, RobotKinematics] = {}
    with local_inputs(plan) as local:  # remote sources fetched into this machine's cache, held while read
        for robot in local.robots:
            sources = [s for s in local.sources if robot.key in {r.key for r in local.robots_for(s.name)}]
            if not sources:
                raise UserError(f"robot '{robot.key}' is driven by no source of this segment")
            result[robot.key] = with_sorting_retry(lambda robot=robot, source=sources[0]: _robot(robot, source))  # type: ignore[misc]
    return result


def _robot(robot: RobotPlan, source: object) -> RobotKinematics:
    mapper = JointValueMapper(robot, source)  # type: ignore[arg-type]
    stream = module_for(source).open_stream(source)  # type: ignore[arg-type]
    values, times = [], {}  # type: ignore[var-annotated]
    for chunk in stream.stream:
        batch = chunk.to_record_batch()
        for field, column in zip(batch.schema, batch.columns, strict=True):
            if (field.metadata or {}).get(b"rerun:kind") == b"index":
                times.setdefault(field.name, []).append(np.asarray(column.cast("int64")))
        vectors = batch.column(batch.schema.get_field_index(stream.component)).flatten()  # one instance per row, as the lens sees it
        raw = raw_matrix(source, vectors, mapper.columns, f"robot '{robot.key}'")  # type: ignore[arg-type]
        block, left_out = mapper.urdf_values(raw)
        values.append(block if left_out is None else np.where(left_out[:, None], np.nan, block))
    problems = Problems()
    check_joint_statistics(mapper, problems)
    problems.raise_if_any()
    tree = cached_tree(robot)
    joint_values = np.concatenate(values) if values else np.zeros((0, len(mapper.joint_names)))
    links, translations, quaternions = _compose(tree, robot.frame_prefix, list(mapper.joint_names), joint_values)
    root = robot.frame_prefix + tree.root_link().name
    return RobotKinematics(robot.key, root, links, {k: np.concatenate(v) for k, v in times.items()}, translations, quaternions)


def _compose(tree: UrdfTree, prefix: str, names: list[str], values: np.ndarray) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Root-frame poses of every link: each joint's local transform, composed from the root down."""
    rows = len(values)
    local_t, local_q = ClosedFormJointTransforms(tree, names).arrays(values)
    moving = {name: index for index, name in enumerate(names)}
    root = tree.root_link().name
    placed_t = {root: np.zeros((rows, 3))}
    placed_q = {root: np.tile([0.0, 0.0, 0.0, 1.0], (rows, 1))}
    children: dict[str, list] = {}
    for joint in tree.joints():
        children.setdefault(joint.parent_link, []).append(joint)
    queue = [root]
    while queue:  # one step per link, over all rows at once
        parent = queue.pop()
        for joint in children.get(parent, []):
            if joint.name in moving:
                t, q = local_t[:, moving[joint.name]], local_q[:, moving[joint.name]]
            else:
                t, q = _static(joint)
                t, q = np.broadcast_to(t, (rows, 3)), np.broadcast_to(q, (rows, 4))
            placed_t[joint.child_link] = placed_t[parent] + rotate(placed_q[parent], t)
            placed_q[joint.child_link] = multiply_quaternions(placed_q[parent], q)
            queue.append(joint.child_link)
    links = tuple(placed_t)
    return (
        tuple(prefix + link for link in links),
        np.stack([placed_t[link] for link in links]),
        np.stack([placed_q[link] for link in links]),
    )


def _static(joint: UrdfJoint) -> tuple[np.ndarray, np.ndarray]:
    """A joint no value drives (fixed, floating, planar): its URDF origin, as Rerun's model logs it."""
    rotation: list[float] = quaternion_from_rpy(*joint.origin_rpy)
    return np.array(joint.origin_xyz, dtype=np.float64), np.array(rotation, dtype=np.float64)

"""Forward kinematics as arrays, for analysis (`urdf_pipeline.forward_kinematics`): every link's pose in its robot's
root frame at every row of a segment, from the same values and joint transforms a run writes.

The source is read as a run reads it (streamed, in time order, the same corrections and checks: a value past its
limits or NaN raises as `run` would); the joint transforms come from the closed form of `joint_fk.py`, in float64,
composed down the URDF tree by its `link_poses`. The result holds every link at every row: 56 bytes per link and
row, so it grows with the segment (unlike a run).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial
from typing import TypeVar

import numpy as np

from ..errors import Problems
from ..plan import RecordingPlan, RobotPlan, SourcePlan
from ..sources import JointValueMapper, module_for, raw_matrix, with_sorting_retry
from .joint_fk import ClosedFormJointTransforms, Pose, rotation_matrices
from .limits_report import check_joint_statistics
from .model_stream import cached_tree
from .remote_inputs import local_inputs

T = TypeVar("T")
ValueBlock = tuple[np.ndarray, dict[str, np.ndarray]]  # (rows x joints URDF values, NaN where left out; timeline -> int64)


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

    @classmethod
    def of(cls, robot: str, root: str, poses: dict[str, Pose], times: dict[str, np.ndarray], prefix: str = "") -> RobotKinematics:
        """From `ClosedFormJointTransforms.link_poses`, its links named with the robot's frame prefix."""
        links = tuple(prefix + link for link in poses)
        return cls(robot, root, links, times, np.stack([t for t, _ in poses.values()]), np.stack([q for _, q in poses.values()]))

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
    return segment_value_blocks(plan, _robot)


def segment_value_blocks(
    plan: RecordingPlan, consume: Callable[[RobotPlan, SourcePlan, JointValueMapper, Iterator[ValueBlock]], T]
) -> dict[str, T]:
    """`consume(robot, source, mapper, blocks)` for every robot of one segment's plan, by robot key: its source read as
    a run reads it, block by block (`value_blocks`), run again from the start when a source turns out unsorted."""
    result: dict[str, T] = {}
    with local_inputs(plan) as local:  # remote sources fetched into this machine's cache, held while read
        for robot, source in robot_sources(local):
            result[robot.key] = with_sorting_retry(partial(_consumed, consume, robot, source))
    return result


def robot_sources(plan: RecordingPlan) -> list[tuple[RobotPlan, SourcePlan]]:
    """Every robot of one segment's plan with the source that drives it (its first)."""
    from ..errors import UserError

    found = []
    for robot in plan.robots:
        sources = [s for s in plan.sources if robot.key in {r.key for r in plan.robots_for(s.name)}]
        if not sources:
            raise UserError(f"robot '{robot.key}' is driven by no source of this segment")
        found.append((robot, sources[0]))
    return found


def _consumed(
    consume: Callable[[RobotPlan, SourcePlan, JointValueMapper, Iterator[ValueBlock]], T], robot: RobotPlan, source: SourcePlan
) -> T:
    mapper = JointValueMapper(robot, source)
    return consume(robot, source, mapper, value_blocks(mapper, source))


def value_blocks(mapper: JointValueMapper, source: SourcePlan) -> Iterator[ValueBlock]:
    """The robot's values after every correction of the config, one block per chunk of its source, with each of the
    source's timelines at every row; no recording is written, and nothing is checked beyond what the mapper records."""
    stream = module_for(source).open_stream(source)
    for chunk in stream.stream:
        batch = chunk.to_record_batch()
        times: dict[str, np.ndarray] = {}
        for field, column in zip(batch.schema, batch.columns, strict=True):
            if (field.metadata or {}).get(b"rerun:kind") == b"index":
                times[field.name] = np.asarray(column.cast("int64"))
        vectors = batch.column(batch.schema.get_field_index(stream.component)).flatten()  # one instance per row, as the lens sees it
        raw = raw_matrix(source, vectors, mapper.columns, f"robot '{mapper.robot.key}'")
        block, left_out = mapper.urdf_values(raw)
        yield (block if left_out is None else np.where(left_out[:, None], np.nan, block)), times


def _robot(robot: RobotPlan, source: SourcePlan, mapper: JointValueMapper, blocks: Iterator[ValueBlock]) -> RobotKinematics:
    values: list[np.ndarray] = []
    times: dict[str, list[np.ndarray]] = {}
    for block, block_times in blocks:
        values.append(block)
        for name, column in block_times.items():
            times.setdefault(name, []).append(column)
    problems = Problems()
    check_joint_statistics(mapper, problems)
    problems.raise_if_any()
    tree = cached_tree(robot)
    joint_values = np.concatenate(values) if values else np.zeros((0, len(mapper.joint_names)))
    poses = ClosedFormJointTransforms(tree, list(mapper.joint_names)).link_poses(joint_values)
    root = robot.frame_prefix + tree.root_link().name
    return RobotKinematics.of(robot.key, root, poses, {k: np.concatenate(v) for k, v in times.items()}, robot.frame_prefix)

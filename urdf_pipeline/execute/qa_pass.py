"""The `qa` command's data pass: every segment's robots read as a run reads them (`segment_value_blocks`: the same
corrections, no recording written), fed block by block into `SegmentQa`, then judged together (`segment_flags`).
The result is one record form (`QaReport.as_data`) that every format of the report renders."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..plan import QA_FLAGS, Plan, QaFlag, RobotPlan, Segment, SourcePlan
from ..sources import JointValueMapper
from .kinematics import ValueBlock, segment_value_blocks
from .model_stream import cached_tree
from .qa_metrics import JointMetrics, SegmentMetrics, SegmentQa, by_joint, segment_flags

QA_VERSION = 1
TIME_KINDS = ("timestamp", "duration")


@dataclass(frozen=True)
class QaReport:
    """Every segment's metrics and flags, in the plan's order; `episodes` holds each segment's LeRobot episode index."""

    segments: tuple[SegmentMetrics, ...]
    flags: tuple[tuple[QaFlag, ...], ...]
    episodes: tuple[int | None, ...]

    def as_data(self) -> dict[str, Any]:
        """The json form (docs/qa.md), the one record every format renders."""
        by_flag = {flag: sum(flag in found for found in self.flags) for flag in QA_FLAGS}
        return {
            "version": QA_VERSION,
            "segments": [_segment_data(s, f) for s, f in zip(self.segments, self.flags, strict=True)],
            "summary": {
                "segments": len(self.segments),
                "flagged": sum(bool(found) for found in self.flags),
                "by_flag": {flag: count for flag, count in by_flag.items() if count},
            },
        }

    def exclusions(self) -> list[int | str]:
        """The flagged segments, as LeRobot's dataset editing takes them: episode indices; a segment that is no LeRobot
        episode (a globbed file, the run's only input) by its segment id."""
        return [
            segment.id if episode is None else episode
            for segment, episode, found in zip(self.segments, self.episodes, self.flags, strict=True)
            if found
        ]


def _segment_data(segment: SegmentMetrics, flags: tuple[QaFlag, ...]) -> dict[str, Any]:
    return {
        "id": segment.id,
        "rows": segment.rows,
        "duration_s": segment.duration_s,
        "flags": list(flags),
        "joints": {name: _joint_data(joint) for name, joint in segment.joints.items()},
        "timing": {
            "max_gap_s": segment.timing.max_gap_s,
            "gaps": segment.timing.gaps,
            "order_violations": segment.timing.order_violations,
        },
        "bias": {},  # compare's calibration bias: not measured by this pass
    }


def _joint_data(joint: JointMetrics) -> dict[str, Any]:
    return {"max_abs_velocity": joint.max_abs_velocity, "p95_abs_jerk": joint.p95_abs_jerk, "static_fraction": joint.static_fraction}


def dataset_qa(plan: Plan) -> QaReport:
    """Every segment of `plan` (its --episodes selection) measured, then flagged against the dataset's own distribution."""
    metrics: list[SegmentMetrics] = []
    angular: dict[str, bool] = {}
    for segment in plan.segments:
        found, kinds = segment_metrics(plan, segment)
        metrics.append(found)
        angular.update(kinds)
    flags = segment_flags(metrics, plan.qa, angular)
    return QaReport(tuple(metrics), tuple(flags), tuple(s.episode for s in plan.segments))


def segment_metrics(plan: Plan, segment: Segment) -> tuple[SegmentMetrics, dict[str, bool]]:
    """One segment's metrics (joints named `ROBOT/JOINT` when it has more than one robot; rows and timing are its first
    robot's), and each joint's kind (True: angular)."""
    many = len(plan.robots) > 1
    qa = plan.qa

    def measure(
        robot: RobotPlan, source: SourcePlan, mapper: JointValueMapper, blocks: Iterator[ValueBlock]
    ) -> tuple[SegmentMetrics, dict[str, bool]]:
        names = [f"{robot.key}/{name}" if many else name for name in mapper.joint_names]
        kinds = _angular(robot, mapper.joint_names)
        count = len(mapper.columns)  # channels first: held and mimic joints have no limits of their own here
        lower = np.full(len(names), np.nan)
        upper = np.full(len(names), np.nan)
        lower[:count], upper[:count] = mapper.lower - mapper.slack, mapper.upper + mapper.slack
        timeline, fps = qa_timeline(source)
        untimed = timeline is None and fps is None  # rows without time: each step counts as 1 s, no duration is said
        measured = SegmentQa(
            segment.id,
            names,
            by_joint(kinds, qa.static_velocity.angle, qa.static_velocity.length),
            lower,
            upper,
            fps=1.0 if untimed else fps,
            gap_seconds=qa.gap_seconds,
            gap_steps=qa.gap_steps,
        )
        for values, times in blocks:
            measured.add(values, times.get(timeline) if timeline else None)
        result = measured.finish()
        if untimed:
            result = replace(result, duration_s=None)
        return result, dict(zip(names, kinds, strict=True))

    found = segment_value_blocks(plan.for_segment(segment), measure)
    results = list(found.values())
    first, kinds = results[0]
    joints = dict(first.joints)
    for other, other_kinds in results[1:]:
        joints.update(other.joints)
        kinds.update(other_kinds)
    return SegmentMetrics(segment.id, first.rows, first.duration_s, joints, first.timing), kinds


def qa_timeline(source: SourcePlan) -> tuple[str | None, float | None]:
    """The time a source's rows have for QA: its time timeline (a LeRobot dataset's `time`, an MCAP topic's stamps, a
    file's timestamp or duration index), else its fps (LeRobot's meta/info.json), else neither."""
    from ..compile import source_timelines

    timed = [name for name, kind in source_timelines(source) if kind in TIME_KINDS]
    fps = getattr(source, "fps", None)
    return (timed[0] if timed else None), (float(fps) if fps else None)


def _angular(robot: RobotPlan, joints: tuple[str, ...]) -> list[bool]:
    tree = cached_tree(robot)
    kinds = []
    for name in joints:
        joint = tree.get_joint_by_name(name)
        kinds.append(joint is None or joint.joint_type != "prismatic")
    return kinds

"""The `qa` command's data pass: every segment's robots read as a run reads them (`segment_value_blocks`: the same
corrections, no recording written), fed block by block into `SegmentQa`, then judged together (`segment_flags`).
The result is one record form (`QaReport.as_data`) that every format of the report renders."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np

from ..plan import QA_FLAGS, Plan, QaFlag, QaPlan, RecordingPlan, RobotPlan, Segment, SourcePlan
from ..sources import JointValueMapper, with_sorting_retry
from .differences import PairDifferences, pair_differences
from .kinematics import ValueBlock, robot_sources, value_blocks
from .manifest_entry import JointDifferences
from .model_stream import cached_tree
from .qa_metrics import JointMetrics, SegmentMetrics, SegmentQa, by_joint, segment_flags
from .remote_inputs import local_inputs

QA_VERSION = 1
TIME_KINDS = ("timestamp", "duration")


@dataclass(frozen=True)
class QaReport:
    """Every segment's metrics and flags, in the plan's order; `episodes` holds each segment's LeRobot episode index."""

    segments: tuple[SegmentMetrics, ...]
    flags: tuple[tuple[QaFlag, ...], ...]
    episodes: tuple[int | None, ...]
    differences: tuple[tuple[JointDifferences, ...], ...] = ()  # per segment: each compared pair's (compare:)

    def as_data(self) -> dict[str, Any]:
        """The json form (docs/qa.md), the one record every format renders."""
        by_flag = {flag: sum(flag in found for found in self.flags) for flag in QA_FLAGS}
        return {
            "version": QA_VERSION,
            "segments": [
                _segment_data(s, f, d)
                for s, f, d in zip(self.segments, self.flags, self.differences or ((),) * len(self.segments), strict=True)
            ],
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


def _segment_data(segment: SegmentMetrics, flags: tuple[QaFlag, ...], differences: tuple[JointDifferences, ...]) -> dict[str, Any]:
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
        "bias": {
            f"{d.copy}/{joint}": {"mean": d.bias_mean[i], "std": d.bias_std[i], "rows": d.bias_rows[i]}
            for d in differences
            for i, joint in enumerate(d.joints[: len(d.bias_rows)])
        },  # compare: the copy's calibration bias per joint (URDF units), over the rows both robots are still
    }


def _joint_data(joint: JointMetrics) -> dict[str, Any]:
    return {"max_abs_velocity": joint.max_abs_velocity, "p95_abs_jerk": joint.p95_abs_jerk, "static_fraction": joint.static_fraction}


def dataset_qa(plan: Plan) -> QaReport:
    """Every segment of `plan` (its --episodes selection) measured, then flagged against the dataset's own distribution."""
    metrics: list[SegmentMetrics] = []
    angular: dict[str, bool] = {}
    compared: list[tuple[JointDifferences, ...]] = []
    for segment in plan.segments:
        found, kinds, differences = segment_metrics(plan, segment)
        metrics.append(found)
        angular.update(kinds)
        compared.append(differences)
    flags = [
        tuple(f for f in QA_FLAGS if f in found or (f == "calibration_bias" and any(any(d.biased) for d in differences)))
        for found, differences in zip(segment_flags(metrics, plan.qa, angular), compared, strict=True)
    ]
    return QaReport(tuple(metrics), tuple(flags), tuple(s.episode for s in plan.segments), tuple(compared))


def segment_metrics(plan: Plan, segment: Segment) -> tuple[SegmentMetrics, dict[str, bool], tuple[JointDifferences, ...]]:
    """One segment's metrics (joints named `ROBOT/JOINT` when it has more than one robot; rows and timing are its first
    robot's), each joint's kind (True: angular), and each compared pair's differences and calibration bias."""
    recording = plan.for_segment(segment)
    with local_inputs(recording) as local:  # remote sources fetched into this machine's cache, held while read
        return with_sorting_retry(partial(_measured, local, segment.id))


def _measured(plan: RecordingPlan, segment_id: str) -> tuple[SegmentMetrics, dict[str, bool], tuple[JointDifferences, ...]]:
    """Every robot's blocks read side by side, the robot with the fewest rows read next: a compared pair's copy and
    measured robot then keep at most about one block of lead on each other (memory bounded by a block)."""
    many = len(plan.robots) > 1
    pairs = pair_differences(plan)
    readers = []
    kinds: dict[str, bool] = {}
    for robot, source in robot_sources(plan):
        mapper = JointValueMapper(robot, source)
        names = [f"{robot.key}/{name}" if many else name for name in mapper.joint_names]
        angular = _angular(robot, mapper.joint_names)
        kinds.update(zip(names, angular, strict=True))
        measured, timeline, untimed = _segment_qa(plan.qa, segment_id, source, mapper, names, angular)
        sides = [pair for pair in pairs if robot.key in (pair.copy, pair.measured)]
        readers.append(_Reader(robot.key, len(robot.channels), value_blocks(mapper, source), measured, timeline, untimed, sides))
    active = list(readers)
    while active:
        reader = min(active, key=lambda r: r.rows)
        block = next(reader.blocks, None)
        if block is None:
            active.remove(reader)
            continue
        values, times = block
        reader.rows += len(values)
        reader.qa.add(values, times.get(reader.timeline) if reader.timeline else None)
        for pair in reader.pairs:
            pair.add(reader.robot, values[:, : reader.driven], None)  # rows left out are NaN: never compared
    results = []
    for reader in readers:
        result = reader.qa.finish()
        results.append(replace(result, duration_s=None) if reader.untimed else result)
    joints = {name: joint for result in results for name, joint in result.joints.items()}
    first = results[0]
    return SegmentMetrics(segment_id, first.rows, first.duration_s, joints, first.timing), kinds, tuple(p.result() for p in pairs)


@dataclass
class _Reader:
    """One robot's blocks and what they feed."""

    robot: str
    driven: int  # its driven joints: the first columns of a block
    blocks: Iterator[ValueBlock]
    qa: SegmentQa
    timeline: str | None
    untimed: bool
    pairs: list[PairDifferences]
    rows: int = 0


def _segment_qa(
    qa: QaPlan, segment_id: str, source: SourcePlan, mapper: JointValueMapper, names: list[str], kinds: list[bool]
) -> tuple[SegmentQa, str | None, bool]:
    """A robot's metrics accumulator, the timeline its rows are timed by, and whether they have no time at all."""
    count = len(mapper.columns)  # channels first: held and mimic joints have no limits of their own here
    lower = np.full(len(names), np.nan)
    upper = np.full(len(names), np.nan)
    lower[:count], upper[:count] = mapper.lower - mapper.slack, mapper.upper + mapper.slack
    timeline, fps = qa_timeline(source)
    untimed = timeline is None and fps is None  # rows without time: each step counts as 1 s, no duration is said
    measured = SegmentQa(
        segment_id,
        names,
        by_joint(kinds, qa.static_velocity.angle, qa.static_velocity.length),
        lower,
        upper,
        fps=1.0 if untimed else fps,
        gap_seconds=qa.gap_seconds,
        gap_steps=qa.gap_steps,
    )
    return measured, timeline, untimed


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

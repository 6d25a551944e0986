"""`compare:`: a commanded copy against its measured robot, gathered during the run's one pass.

Each robot's FK lens hands its (rows x joints) URDF values to its `ValuePreview`, which passes them on here. Rows are
matched one to one, in order (compile allows only sources whose rows are the same rows); the side that runs ahead
keeps its rows until the other catches up, so memory holds at most the lead one stream has on the other. Per joint:
the largest absolute difference and the rows beyond the threshold; rows either robot left out are not compared.
"""

from __future__ import annotations

import threading

import numpy as np

from ..plan import Comparison, RobotPlan
from .manifest_entry import JointDifferences


class PairDifferences:
    """One copy and its measured robot: both sides' driven values in, per-joint maxima and counts out."""

    def __init__(self, copy: RobotPlan, measured: RobotPlan, comparison: Comparison) -> None:
        self.copy, self.measured = copy.key, measured.key
        self.joints = tuple(c.joint for c in copy.channels)
        position = {c.joint: i for i, c in enumerate(measured.channels)}
        self.order = np.array([position[joint] for joint in self.joints], dtype=np.intp)  # measured columns, copy's order
        self.thresholds = np.array(comparison.thresholds, dtype=np.float64)
        self.written = comparison.written
        self.units = comparison.units
        self.largest = np.zeros(len(self.joints))
        self.beyond = np.zeros(len(self.joints), dtype=np.int64)
        self.rows_beyond = 0
        self.compared = 0
        self.counts = {self.copy: 0, self.measured: 0}
        self.pending: dict[str, list[np.ndarray]] = {self.copy: [], self.measured: []}  # rows not yet matched; NaN: left out
        self._lock = threading.Lock()  # lens callbacks may run on several of Rerun's threads

    def add(self, robot: str, driven: np.ndarray, left_out: np.ndarray | None) -> None:
        """A batch of one side's driven values (its channels' order), rows in order."""
        rows = driven if left_out is None else np.where(left_out[:, None], np.nan, driven)
        if robot == self.measured:
            rows = rows[:, self.order]
        with self._lock:
            self.counts[robot] += len(rows)
            self.pending[robot].append(rows)
            self._match()

    def _match(self) -> None:
        ours, theirs = (np.concatenate(self.pending[key]) if self.pending[key] else None for key in (self.copy, self.measured))
        if ours is None or theirs is None:
            return
        matched = min(len(ours), len(theirs))
        self.pending = {self.copy: [ours[matched:]], self.measured: [theirs[matched:]]}
        difference = np.abs(ours[:matched] - theirs[:matched])  # NaN where either side left the row out
        valid = ~np.isnan(difference).any(axis=1)
        difference = difference[valid]
        if not len(difference):
            return
        over = difference > self.thresholds
        self.largest = np.maximum(self.largest, difference.max(axis=0))
        self.beyond += over.sum(axis=0)
        self.rows_beyond += int(over.any(axis=1).sum())
        self.compared += len(difference)

    def result(self) -> JointDifferences:
        return JointDifferences(
            copy=self.copy,
            measured=self.measured,
            threshold=self.written,
            rows=self.compared,
            rows_beyond=self.rows_beyond,
            unmatched=abs(self.counts[self.copy] - self.counts[self.measured]),
            joints=self.joints,
            largest=tuple(float(v) for v in self.largest),
            beyond=tuple(int(v) for v in self.beyond),
            units=self.units,
        )


def pair_differences(robots: tuple[RobotPlan, ...]) -> list[PairDifferences]:
    """One accumulator per copy whose measured robot is in this recording."""
    by_key = {robot.key: robot for robot in robots}
    return [
        PairDifferences(robot, by_key[robot.compare.robot], robot.compare)
        for robot in robots
        if robot.compare is not None and robot.compare.robot in by_key
    ]

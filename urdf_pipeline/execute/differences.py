"""`compare:`: a commanded copy against its measured robot, gathered during the run's one pass.

Each robot's FK lens hands its (rows x joints) URDF values to its `ValuePreview`, which passes them on here. Rows are
matched one to one, in order (compile allows only sources whose rows are the same rows); the side that runs ahead
keeps its rows until the other catches up, so memory holds at most the lead one stream has on the other. Per joint:
the largest absolute difference and the rows beyond the threshold; rows either robot left out are not compared.

Calibration bias, in the same pass: per joint, the mean and standard deviation of (copy - measured) over the matched
rows where both robots are still at that joint (the step from the row before below `qa.static_velocity` times the
row's time step: 1/fps of the copy's source, else 1 s), from running sums shifted by the first still difference (no
cancellation when the bias dwarfs the noise). A row after a row left out has no step: it is not counted as still.
"""

from __future__ import annotations

import threading

import numpy as np

from ..compile import LINEAR_UNITS
from ..plan import Comparison, QaPlan, RecordingPlan, RobotPlan
from .manifest_entry import JointDifferences


class PairDifferences:
    """One copy and its measured robot: both sides' driven values in, per-joint maxima and counts out."""

    def __init__(self, copy: RobotPlan, measured: RobotPlan, comparison: Comparison, qa: QaPlan | None = None, step: float = 1.0) -> None:
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
        qa = qa or QaPlan()
        count = len(self.joints)
        angular = [
            unit not in LINEAR_UNITS if len(comparison.units) == count else limit == comparison.angle
            for unit, limit in zip(comparison.units or ("",) * count, self.thresholds, strict=True)
        ]
        self.still_step = np.array([qa.static_velocity.for_joint(a) * step for a in angular])  # largest still step
        self.bias_limit = np.array([qa.bias.for_joint(a) for a in angular])
        self.previous = (np.full((1, count), np.nan), np.full((1, count), np.nan))  # the last matched rows, both sides
        self.shift = np.full(count, np.nan)  # the first still difference per joint
        self.still_rows = np.zeros(count, dtype=np.int64)
        self.sum = np.zeros(count)
        self.sum_squares = np.zeros(count)
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
        if matched:
            self._bias(ours[:matched], theirs[:matched])
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

    def _bias(self, ours: np.ndarray, theirs: np.ndarray) -> None:
        """Running sums of (copy - measured) over the rows both robots are still at (NaN steps are not still)."""
        with np.errstate(invalid="ignore"):
            still = (np.abs(np.diff(np.concatenate([self.previous[0], ours]), axis=0)) < self.still_step) & (
                np.abs(np.diff(np.concatenate([self.previous[1], theirs]), axis=0)) < self.still_step
            )
        self.previous = (ours[-1:], theirs[-1:])
        signed = ours - theirs
        first = still.argmax(axis=0)
        new = np.isnan(self.shift) & still.any(axis=0)
        self.shift[new] = signed[first[new], np.flatnonzero(new)]
        shifted = np.where(still, signed - np.nan_to_num(self.shift), 0.0)
        self.still_rows += still.sum(axis=0)
        self.sum += shifted.sum(axis=0)
        self.sum_squares += (shifted * shifted).sum(axis=0)

    def result(self) -> JointDifferences:
        rows = np.maximum(self.still_rows, 1)
        average = self.sum / rows
        mean = np.where(self.still_rows > 0, np.nan_to_num(self.shift) + average, 0.0)
        std = np.sqrt(np.maximum(self.sum_squares / rows - average * average, 0.0))
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
            bias_rows=tuple(int(n) for n in self.still_rows),
            bias_mean=tuple(float(m) for m in mean),
            bias_std=tuple(float(s) for s in std),
            biased=tuple(bool(b) for b in (self.still_rows > 0) & (np.abs(mean) > self.bias_limit)),
        )


def pair_differences(plan: RecordingPlan) -> list[PairDifferences]:
    """One accumulator per copy whose measured robot is in this recording; a row's time step is 1/fps of the copy's
    source where it says its fps (a LeRobot dataset), else 1 s."""
    by_key = {robot.key: robot for robot in plan.robots}
    pairs = []
    for robot in plan.robots:
        if robot.compare is not None and robot.compare.robot in by_key:
            fps = next((getattr(s, "fps", None) for s in plan.sources if s.name == robot.source), None)
            pairs.append(PairDifferences(robot, by_key[robot.compare.robot], robot.compare, plan.qa, 1.0 / fps if fps else 1.0))
    return pairs

"""The QA metrics of one segment, fed block by block (memory bounded by one block, never the episode's length), and
the dataset-level step that turns every segment's metrics into its flags. numpy only: the `qa` command and `run` feed
it the corrected joint values they already read. docs/qa.md defines each number.

Differences carry across blocks: the last 3 rows (and their times) are kept, so any split of the rows gives the same
numbers. The p95 |jerk| comes from a fixed log-spaced histogram (JERK_BINS_PER_DECADE): each order statistic is read
as its bin's geometric centre, within JERK_PRECISION (relative) of np.percentile's, for |jerk| in
[10**JERK_LOG_MIN, 10**JERK_LOG_MAX]."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..plan import QA_FLAGS, QaFlag, QaPlan

JERK_BINS_PER_DECADE = 200
JERK_LOG_MIN, JERK_LOG_MAX = -12, 18  # |jerk| (URDF units / s^3) resolved by the histogram; beyond, clamped to its ends
JERK_BINS = (JERK_LOG_MAX - JERK_LOG_MIN) * JERK_BINS_PER_DECADE
JERK_PRECISION = 10 ** (0.5 / JERK_BINS_PER_DECADE) - 1  # 0.58%: half a bin, relative
NOMINAL_STEPS = 1000  # without fps, the nominal step is the median of a segment's first this many positive steps
CARRIED = 3  # rows carried across blocks: a jerk needs four consecutive rows
IQR_FLOOR = 0.1  # length_outlier: the IQR counts as at least this share of the median rows


@dataclass(frozen=True)
class JointMetrics:
    """One joint's numbers over a segment (None where no step could say: fewer rows, NaN, or no valid time step)."""

    max_abs_velocity: float | None
    p95_abs_jerk: float | None
    max_abs_jerk: float | None
    max_jerk_row: int | None  # the row (from 0) the largest |jerk| ends at: a one-frame jump at k gives k + 1
    static_fraction: float | None  # of the steps with a velocity, the share below the static threshold
    nan: int  # non-finite values
    limits: int  # finite values beyond the limits and slack


@dataclass(frozen=True)
class TimingMetrics:
    """The segment's steps between consecutive timestamps."""

    max_gap_s: float | None
    gaps: int  # steps above the gap tolerance
    order_violations: int  # timestamps not after the one before (equal, earlier or NaN)
    nominal_step_s: float | None  # 1/fps, or the median of the first NOMINAL_STEPS positive steps


@dataclass(frozen=True)
class SegmentMetrics:
    id: str
    rows: int
    duration_s: float | None  # last - first timestamp; without timestamps (rows - 1) / fps
    joints: dict[str, JointMetrics]
    timing: TimingMetrics


def by_joint(kinds: Sequence[bool], angle: float, length: float) -> np.ndarray:
    """A threshold by joint kind (a `ByKind` of the QaPlan) as one value per joint (True: angular)."""
    return np.array([angle if angular else length for angular in kinds], dtype=np.float64)


class SegmentQa:
    """The streaming accumulators of one segment: `add` each block of rows (values: rows x joints, URDF units,
    float64, NaN allowed; times: seconds as float64 or nanoseconds as int64, or None with `fps`), then `finish`."""

    def __init__(
        self,
        segment_id: str,
        names: Sequence[str],
        static_velocity: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        *,
        fps: float | None = None,
        gap_seconds: float | None = None,
        gap_steps: float = QaPlan().gap_steps,
    ) -> None:
        self.id, self.names = segment_id, tuple(names)
        width = len(self.names)
        self.static, self.lower, self.upper = static_velocity, lower, upper  # limits with the slack included (NaN: none)
        self.fps, self.gap_seconds, self.gap_steps = fps, gap_seconds, gap_steps
        self.nominal: float | None = 1.0 / fps if fps else None
        self.rows = 0
        self.first_time: np.ndarray | None = None  # the first and last timestamps as given (int64 ns stay exact)
        self.last_time: np.ndarray | None = None
        self.tail_values = np.empty((0, width))
        self.tail_times: np.ndarray | None = None
        self.max_velocity = np.full(width, -np.inf)
        self.max_jerk = np.full(width, -np.inf)
        self.max_jerk_row = np.full(width, -1, dtype=np.int64)
        self.jerk_histogram = np.zeros((width, JERK_BINS + 1), dtype=np.int64)  # the last bin: the values not counted
        self.jerk_zeros = np.zeros(width, dtype=np.int64)
        self.still = np.zeros(width, dtype=np.int64)
        self.moving_steps = np.zeros(width, dtype=np.int64)  # steps with a finite velocity
        self.nan = np.zeros(width, dtype=np.int64)
        self.beyond = np.zeros(width, dtype=np.int64)
        self.max_gap = -np.inf
        self.gaps = 0
        self.order_violations = 0
        self.early_steps: list[np.ndarray] = []  # the first positive steps, until the nominal step is known
        self.early_count = 0

    def add(self, values: np.ndarray, times: np.ndarray | None = None) -> None:
        """One block of consecutive rows."""
        rows = values.shape[0]
        if rows == 0:
            return
        if times is None and not self.fps:
            raise ValueError("a segment without timestamps needs its fps")
        finite = np.isfinite(values)
        all_finite = bool(finite.all())  # a whole-array test is cheap; per-joint counts only when they can be non-zero
        if not all_finite:
            self.nan += rows - finite.sum(axis=0)
        with np.errstate(invalid="ignore"):
            beyond = (values < self.lower) | (values > self.upper)
            if not all_finite:
                beyond &= finite
            if beyond.any():
                self.beyond += beyond.sum(axis=0)
        carried = self.tail_values.shape[0]
        joined = np.concatenate([self.tail_values, values]) if carried else values
        steps = self._steps(joined.shape[0], times)
        if times is not None:
            self._timing(steps[max(carried - 1, 0) :], times)
        reduced, source, constant = _moving_columns(joined)
        with np.errstate(invalid="ignore", divide="ignore"):
            step = (steps if (steps > 0).all() else np.where(steps > 0, steps, np.nan))[:, None]  # not forward: no derivative
            velocity = np.diff(reduced, axis=0)
            velocity /= step
            acceleration = np.diff(velocity, axis=0)
            acceleration /= step[1:]
            jerk = np.diff(acceleration, axis=0)
            jerk /= step[2:]
        self._velocity(velocity[max(carried - 1, 0) :], source, constant)
        self._jerk(jerk[max(carried - 3, 0) :], source, constant, first_row=self.rows + max(3 - carried, 0))
        self.rows += rows
        self.tail_values = joined[-CARRIED:].copy()
        if times is not None:
            previous = self.tail_times
            joined_times = np.concatenate([previous, times]) if previous is not None and previous.size else times
            self.tail_times = joined_times[-CARRIED:].copy()

    def _steps(self, count: int, times: np.ndarray | None, carried: bool = True) -> np.ndarray:
        """The time steps (s) between the joined rows (the carried ones first, with `carried`)."""
        if times is None:
            assert self.fps
            return np.full(max(count - 1, 0), 1.0 / self.fps)
        tail = self.tail_times if carried else None
        joined = np.concatenate([tail, times]) if tail is not None and tail.size else times
        if joined.dtype.kind in "iu":
            return np.diff(joined.astype(np.int64)).astype(np.float64) / 1e9
        return np.diff(joined.astype(np.float64))

    def _timing(self, steps: np.ndarray, times: np.ndarray) -> None:
        if self.first_time is None:
            self.first_time = times[:1].copy()
        self.last_time = times[-1:].copy()
        if not steps.size:
            return
        with np.errstate(invalid="ignore"):
            self.order_violations += int((~(steps > 0)).sum())
            self.max_gap = max(self.max_gap, float(np.nanmax(steps)) if np.isfinite(steps).any() else -np.inf)
            forward = steps[np.isfinite(steps) & (steps > 0)]
        if self.gap_seconds is not None:
            self.gaps += int((forward > self.gap_seconds).sum())
        if self.nominal is None:  # the first positive steps wait for the nominal step they are judged by
            early = forward[: NOMINAL_STEPS - self.early_count]
            self.early_steps.append(early)
            self.early_count += early.size
            forward = forward[early.size :]
            if self.early_count >= NOMINAL_STEPS:
                self._settle_nominal()
        if self.nominal is not None and self.gap_seconds is None:
            self.gaps += int((forward > self.gap_steps * self.nominal).sum())

    def _settle_nominal(self) -> None:
        """The nominal step from the first positive steps, and the gaps among them."""
        early = np.concatenate(self.early_steps) if self.early_steps else np.empty(0)
        self.early_steps = []
        if early.size:
            self.nominal = float(np.median(early))
            if self.gap_seconds is None:
                self.gaps += int((early > self.gap_steps * self.nominal).sum())

    def _velocity(self, velocity: np.ndarray, source: np.ndarray, constant: np.ndarray) -> None:
        """`velocity` of the reduced columns (`_moving_columns`): `source` maps each joint to its column."""
        speed = np.abs(velocity)
        valid = np.isfinite(speed)
        every = bool(valid.all())
        count = np.full(speed.shape[1], speed.shape[0]) if every else valid.sum(axis=0)
        static = np.full(speed.shape[1], np.inf)
        static[source[~constant]] = self.static[~constant]
        still = (speed < static).sum(axis=0)[source]  # NaN and inf are never below
        still[constant] = np.where(0 < self.static[constant], count[-1], 0)  # a constant joint's speed: 0 where valid
        self.moving_steps += count[source]
        self.still += still
        if speed.shape[0]:
            fastest = (speed if every else np.where(valid, speed, -np.inf)).max(axis=0)
            self.max_velocity = np.fmax(self.max_velocity, fastest[source])

    def _jerk(self, jerk: np.ndarray, source: np.ndarray, constant: np.ndarray, first_row: int) -> None:
        """|jerk| of the reduced columns into the histograms and the maxima; `first_row` is the row the first jerk ends at."""
        if not jerk.shape[0]:
            return
        size = np.abs(jerk)
        valid = np.isfinite(size)
        masked = size if valid.all() else np.where(valid, size, -np.inf)
        block_max = masked.max(axis=0)[source]
        better = block_max > self.max_jerk
        if better.any():  # the row of a new maximum, for the columns that have one
            needed = np.zeros(size.shape[1], dtype=bool)
            needed[source[better]] = True
            at = np.zeros(size.shape[1], dtype=np.int64)
            at[needed] = masked[:, needed].argmax(axis=0)
            self.max_jerk = np.where(better, block_max, self.max_jerk)
            self.max_jerk_row = np.where(better, first_row + at[source], self.max_jerk_row)
        zero = size == 0
        self.jerk_zeros += zero.sum(axis=0)[source]
        moving = np.flatnonzero(~constant)  # a constant joint's jerk is 0 or NaN: never in the histogram
        if not moving.size:
            return
        part = size[:, : moving.size]  # their columns, in order: all but the zero column
        positive = ~zero[:, : moving.size] if masked is size else valid[:, : moving.size] & ~zero[:, : moving.size]
        with np.errstate(divide="ignore", invalid="ignore"):
            index = np.log10(part)
        index -= JERK_LOG_MIN
        index *= JERK_BINS_PER_DECADE
        np.floor(index, out=index)
        np.clip(index, 0, JERK_BINS - 1, out=index)
        bins = (index if positive.all() else np.where(positive, index, JERK_BINS)).astype(np.int64)  # not positive: dropped
        first, last = moving[0], moving[-1] + 1  # only the rows of the joints that moved are touched
        bins += (moving - first) * (JERK_BINS + 1)
        counts = np.bincount(bins.ravel(), minlength=(last - first) * (JERK_BINS + 1))
        self.jerk_histogram[first:last] += counts.reshape(last - first, JERK_BINS + 1)

    def finish(self) -> SegmentMetrics:
        if self.nominal is None and self.tail_times is not None:
            self._settle_nominal()
        joints = {
            name: JointMetrics(
                _or_none(self.max_velocity[j]),
                _p95(self.jerk_zeros[j], self.jerk_histogram[j, :JERK_BINS]),
                _or_none(self.max_jerk[j]),
                int(self.max_jerk_row[j]) if self.max_jerk_row[j] >= 0 else None,
                float(self.still[j] / self.moving_steps[j]) if self.moving_steps[j] else None,
                int(self.nan[j]),
                int(self.beyond[j]),
            )
            for j, name in enumerate(self.names)
        }
        if self.first_time is not None and self.last_time is not None:
            duration: float | None = float(self._steps(2, np.concatenate([self.first_time, self.last_time]), carried=False)[0])
        else:
            duration = (self.rows - 1) / self.fps if self.fps and self.rows else None
        timing = TimingMetrics(_or_none(self.max_gap), self.gaps, self.order_violations, self.nominal)
        return SegmentMetrics(self.id, self.rows, duration, joints, timing)


def _moving_columns(joined: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The columns a block's derivatives are computed on, each joint's column in them, and which joints are constant:
    joints whose rows all hold one finite value (a held joint, a still block) share one column of zeros, whose
    differences are exactly theirs (0, or NaN where the step is not forward), so the work grows with the joints that
    move only."""
    constant = (joined == joined[:1]).all(axis=0) & np.isfinite(joined[0])
    if not constant.any():
        return joined, np.arange(joined.shape[1]), constant
    moving = np.flatnonzero(~constant)
    reduced = np.zeros((joined.shape[0], moving.size + 1), dtype=joined.dtype)
    reduced[:, : moving.size] = joined[:, moving]
    source = np.full(joined.shape[1], moving.size)
    source[moving] = np.arange(moving.size)
    return reduced, source, constant


def _or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _bin_value(index: int) -> float:
    """The geometric centre of a histogram bin."""
    return float(10 ** (JERK_LOG_MIN + (index + 0.5) / JERK_BINS_PER_DECADE))


def _p95(zeros: int, histogram: np.ndarray) -> float | None:
    """np.percentile(|jerk|, 95)'s linear interpolation between two order statistics, each read from the histogram."""
    count = int(zeros + histogram.sum())
    if not count:
        return None
    position = 0.95 * (count - 1)
    low = math.floor(position)
    cumulative = np.cumsum(histogram)

    def order_statistic(rank: int) -> float:
        if rank < zeros:
            return 0.0
        return _bin_value(int(np.searchsorted(cumulative, rank - zeros, side="right")))

    below = order_statistic(low)
    above = order_statistic(min(low + 1, count - 1))
    return below + (above - below) * (position - low)


def segment_flags(segments: Sequence[SegmentMetrics], qa: QaPlan, angular: Mapping[str, bool]) -> list[tuple[QaFlag, ...]]:
    """Each segment's flags (in QA_FLAGS order; calibration_bias is compare's, not here), judged against the
    dataset's own distribution: `angular` gives each joint's kind for the thresholds by kind."""
    references = _jerk_references(segments)
    rows = np.array([s.rows for s in segments], dtype=np.float64)
    low, high = -math.inf, math.inf
    if rows.size:
        q1, median, q3 = np.percentile(rows, [25, 50, 75])
        spread = max(float(q3 - q1), IQR_FLOOR * float(median))
        low, high = q1 - qa.length_iqr * spread, q3 + qa.length_iqr * spread
    flags: list[tuple[QaFlag, ...]] = []
    for segment in segments:
        found: set[QaFlag] = set()
        if _spikes(segment, qa, references, angular):
            found.add("spike")
        fractions = [j.static_fraction for j in segment.joints.values() if j.static_fraction is not None]
        if fractions and min(fractions) >= qa.static_share:
            found.add("static")
        if not low <= segment.rows <= high:
            found.add("length_outlier")
        if segment.timing.gaps:
            found.add("timestamp_gap")
        if segment.timing.order_violations:
            found.add("timestamp_order")
        if any(j.limits for j in segment.joints.values()):
            found.add("limits")
        if any(j.nan for j in segment.joints.values()):
            found.add("nan")
        flags.append(tuple(flag for flag in QA_FLAGS if flag in found))
    return flags


def _jerk_references(segments: Sequence[SegmentMetrics]) -> dict[str, float]:
    """Each joint's typical p95 |jerk|: the median over the segments that have one (rate- and noise-independent)."""
    by_name: dict[str, list[float]] = {}
    for segment in segments:
        for name, joint in segment.joints.items():
            if joint.p95_abs_jerk is not None:
                by_name.setdefault(name, []).append(joint.p95_abs_jerk)
    found = {name: float(np.median(values)) for name, values in by_name.items()}
    return found


def _spikes(segment: SegmentMetrics, qa: QaPlan, references: Mapping[str, float], angular: Mapping[str, bool]) -> bool:
    for name, joint in segment.joints.items():
        if joint.max_abs_jerk is None:
            continue
        reference = references.get(name, 0.0)
        if reference > 0 and joint.max_abs_jerk > qa.spike_factor * reference:
            return True
        if qa.spike_jerk is not None and joint.max_abs_jerk > qa.spike_jerk.for_joint(angular.get(name, True)):
            return True
    return False

"""Source vectors -> URDF joint values, on whole columns with numpy, with limit statistics per joint.

Order of corrections (see plan.JointChannel): NaN policy, wrap, linear map (unit * scale * sign + offset,
or source_range onto the joint's range), limits (clamp within slack), then <mimic> joints.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from ..errors import UserError
from ..plan import NamedSource, RobotPlan
from .named_rows import is_named_rows, named_matrix


@dataclass
class ChannelStats:
    """Per mapped joint, accumulated over every batch; reported once, never per row."""

    clamped_rows: int = 0  # outside the limits, within the slack: clamped
    clamped_worst_excess: float = 0.0
    clamped_worst_raw: float = float("nan")
    beyond_rows: int = 0  # beyond the slack
    beyond_worst_excess: float = 0.0
    beyond_worst_raw: float = float("nan")
    nonfinite_rows: int = 0
    first_nonfinite_row: int = -1  # row number in the source, counting from 0
    raw_min: float = float("inf")  # finite raw values (after wrap) of the rows logged: which unit they fit, if refused
    raw_max: float = float("-inf")


@dataclass
class RobotStats:
    rows: int = 0
    dropped_rows: int = 0  # nan: drop_row, or hold_last before any valid value
    filled_rows: int = 0  # nan: hold_last
    channels: list[ChannelStats] = field(default_factory=list)


def wrapped(values: np.ndarray, center: np.ndarray | float, period: np.ndarray | float) -> np.ndarray:
    """Values moved by whole periods into [center - period/2, center + period/2): a servo's 350 deg is -10 deg."""
    low = center - np.asarray(period) / 2
    return low + np.mod(values - low, period)


def vector_matrix(source: NamedSource, vectors: pa.Array) -> np.ndarray:
    """(rows x names) float64 from one list of values per row; every row holds exactly one value per name."""
    width = len(source.names)
    if vectors.null_count:
        raise UserError(f"source '{source.name}' has {vectors.null_count} rows without values", source.where)
    if isinstance(vectors, pa.FixedSizeListArray):
        found = vectors.type.list_size
        lengths_ok = found == width
    else:
        lengths = vectors.value_lengths().to_numpy(zero_copy_only=False)
        lengths_ok = bool(np.all(lengths == width))
        found = int(lengths[lengths != width][0]) if not lengths_ok else width
    if not lengths_ok:
        raise UserError(
            f"source '{source.name}' has rows of {found} values but {width} names; names and values must match one to one", source.where
        )
    flat = vectors.flatten().to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
    return flat.reshape(len(vectors), width)


def raw_matrix(source: NamedSource, rows: pa.Array, required: np.ndarray | None = None, consumer: str = "") -> np.ndarray:
    """Any source's rows as a (rows x names) matrix: vectors, or rows that name their values (mapped by name: a row
    lacking a `required` position is an error; names nobody reads may be absent and stay NaN)."""
    if is_named_rows(rows):
        needed = np.empty(0, dtype=np.intp) if required is None else required
        return named_matrix(rows, source, needed, consumer or f"source '{source.name}'")
    return vector_matrix(source, rows)


class JointValueMapper:
    """Turns (rows x source width) matrices into (rows x joints) URDF values for one robot."""

    def __init__(self, robot: RobotPlan, source: NamedSource) -> None:
        self.robot = robot
        self.source = source
        self.width = len(source.names)
        channels = robot.channels
        self.columns = np.array([c.source_index for c in channels], dtype=np.intp)
        self.gain = np.array([c.gain for c in channels], dtype=np.float64)
        self.bias = np.array([c.bias for c in channels], dtype=np.float64)
        self.wrap = np.array([c.wrap if c.wrap else np.nan for c in channels], dtype=np.float64)
        self.wrap_center = np.array([c.wrap_center for c in channels], dtype=np.float64)
        self.any_wrap = bool(np.isfinite(self.wrap).any())
        self.nan_policy = robot.nan_policy
        self._last_valid: np.ndarray | None = None  # hold_last carries the last valid row across batches
        self.lower = np.array([c.lower if c.lower is not None else -np.inf for c in channels], dtype=np.float64)
        self.upper = np.array([c.upper if c.upper is not None else np.inf for c in channels], dtype=np.float64)
        self.slack = np.array([c.slack for c in channels], dtype=np.float64)
        self.held = np.array([h.value for h in robot.holds], dtype=np.float64)
        self.joint_names: tuple[str, ...] = (
            *(c.joint for c in channels),
            *(h.joint for h in robot.holds),
            *(m.joint for m in robot.mimics),
        )
        position = {name: i for i, name in enumerate(self.joint_names)}
        self.mimic_plan = [(position[m.joint], position[m.driver], m.multiplier, m.offset) for m in robot.mimics]
        self.clamp_all = robot.on_violation == "clamp"
        self.stats = RobotStats(channels=[ChannelStats() for _ in channels])
        self._lock = threading.Lock()

    def urdf_values(self, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(rows x width) raw values -> ((rows x joints) URDF values, mask of rows to leave out or None).

        Batches arrive in source order (Rerun's streams process chunks sequentially), which the row
        numbers in messages and hold_last's carry-over rely on.
        """
        picked = raw[:, self.columns]
        nonfinite = ~np.isfinite(picked)
        with self._lock:
            first_row = self.stats.rows
            self.stats.rows += len(picked)
        drop = self._apply_nan_policy(picked, nonfinite)
        if self.any_wrap:
            picked_for_values = np.where(np.isnan(self.wrap), picked, wrapped(picked, self.wrap_center, self.wrap))
        else:
            picked_for_values = picked
        values = picked_for_values * self.gain + self.bias
        with np.errstate(invalid="ignore"):  # inf - inf for non-finite values; they are reported separately
            excess = np.maximum(np.maximum(self.lower - values, values - self.upper), 0.0)
        excess[~np.isfinite(values)] = 0.0
        if drop is not None:
            excess[drop] = 0.0
        beyond = excess > self.slack
        within = (excess > 0.0) & ~beyond
        clamp_mask = within | (beyond & self.clamp_all)
        if clamp_mask.any():
            values = np.where(clamp_mask, np.clip(values, self.lower, self.upper), values)
        self._record(picked, excess, within, beyond, nonfinite if self.nan_policy == "error" else np.zeros_like(nonfinite), first_row)
        self._record_range(picked_for_values, drop)
        rows = len(raw)
        full = np.empty((rows, len(self.joint_names)), dtype=np.float64)
        count = len(self.columns)
        full[:, :count] = values
        full[:, count : count + len(self.held)] = self.held
        for target, driver, multiplier, offset in self.mimic_plan:
            full[:, target] = full[:, driver] * multiplier + offset
        if drop is not None:
            full[drop] = 0.0  # placeholders: these rows are logged as nulls
        return full, drop

    def _apply_nan_policy(self, picked: np.ndarray, nonfinite: np.ndarray) -> np.ndarray | None:
        """drop_row: rows with any NaN are left out; hold_last: NaNs take the last valid value (in place)."""
        if self.nan_policy == "error" or not nonfinite.any():
            if self.nan_policy == "hold_last" and len(picked):
                self._last_valid = picked[-1].copy()
            return None
        bad_rows: np.ndarray = np.asarray(nonfinite.any(axis=1))
        if self.nan_policy == "drop_row":
            with self._lock:
                self.stats.dropped_rows += int(bad_rows.sum())
            return bad_rows
        # hold_last: forward-fill each column from the last finite value, carried over from earlier batches
        rows = np.arange(len(picked))[:, None]
        source_row = np.maximum.accumulate(np.where(nonfinite, -1, rows), axis=0)
        filled = np.take_along_axis(picked, np.maximum(source_row, 0), axis=0)
        if self._last_valid is not None:
            filled = np.where(source_row < 0, self._last_valid, filled)
            no_value: np.ndarray = np.zeros(len(picked), dtype=bool)
        else:
            no_value = np.asarray((source_row < 0).any(axis=1))
        picked[:] = filled
        self._last_valid = picked[-1].copy() if not no_value[-1] else self._last_valid
        with self._lock:
            self.stats.filled_rows += int((bad_rows & ~no_value).sum())
            self.stats.dropped_rows += int(no_value.sum())
        return no_value if no_value.any() else None

    def _record_range(self, values: np.ndarray, drop: np.ndarray | None) -> None:
        """Each column's finite min and max, whole columns at once (no warning for a column without finite values)."""
        if not len(values):
            return
        finite = np.isfinite(values)
        if drop is not None:
            finite &= ~drop[:, None]
        low = np.where(finite, values, np.inf).min(axis=0)
        high = np.where(finite, values, -np.inf).max(axis=0)
        with self._lock:
            for i, stats in enumerate(self.stats.channels):
                stats.raw_min, stats.raw_max = min(stats.raw_min, float(low[i])), max(stats.raw_max, float(high[i]))

    def _record(
        self, picked: np.ndarray, excess: np.ndarray, within: np.ndarray, beyond: np.ndarray, nonfinite: np.ndarray, first_row: int
    ) -> None:
        within_counts = within.sum(axis=0)
        beyond_counts = beyond.sum(axis=0)
        nonfinite_counts = nonfinite.sum(axis=0)
        empty = np.zeros(len(self.columns), dtype=np.intp)
        within_arg = np.where(within, excess, -1.0).argmax(axis=0) if len(picked) else empty
        beyond_arg = np.where(beyond, excess, -1.0).argmax(axis=0) if len(picked) else empty
        first_nonfinite = nonfinite.argmax(axis=0) if len(picked) else empty
        with self._lock:
            for i, stats in enumerate(self.stats.channels):
                if within_counts[i]:
                    stats.clamped_rows += int(within_counts[i])
                    worst = float(excess[within_arg[i], i])
                    if worst > stats.clamped_worst_excess:
                        stats.clamped_worst_excess, stats.clamped_worst_raw = worst, float(picked[within_arg[i], i])
                if beyond_counts[i]:
                    stats.beyond_rows += int(beyond_counts[i])
                    worst = float(excess[beyond_arg[i], i])
                    if worst > stats.beyond_worst_excess:
                        stats.beyond_worst_excess, stats.beyond_worst_raw = worst, float(picked[beyond_arg[i], i])
                if nonfinite_counts[i]:
                    if stats.first_nonfinite_row < 0:
                        stats.first_nonfinite_row = first_row + int(first_nonfinite[i])
                    stats.nonfinite_rows += int(nonfinite_counts[i])

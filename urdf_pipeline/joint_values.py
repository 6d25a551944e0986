"""Source vectors -> URDF joint values, on whole columns with numpy, with limit statistics per joint.

Order of corrections: unit conversion, sign, offset; then limits (clamp within slack), then <mimic> joints.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from .errors import UserError
from .plan import RobotPlan, SourcePlan


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


@dataclass
class RobotStats:
    rows: int = 0
    channels: list[ChannelStats] = field(default_factory=list)


class JointValueMapper:
    """Turns (rows x source width) matrices into (rows x joints) URDF values for one robot."""

    def __init__(self, robot: RobotPlan, source: SourcePlan) -> None:
        self.robot = robot
        self.source = source
        self.width = len(source.names)
        channels = robot.channels
        self.columns = np.array([c.source_index for c in channels], dtype=np.intp)
        self.scale = np.array([c.factor * c.sign for c in channels], dtype=np.float64)
        self.offset = np.array([c.offset for c in channels], dtype=np.float64)
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
        self.clamp_none = robot.on_violation == "ignore"
        self.stats = RobotStats(channels=[ChannelStats() for _ in channels])
        self._lock = threading.Lock()

    def matrix(self, vectors: pa.Array) -> np.ndarray:
        """One row per vector; every row must hold exactly one value per source name."""
        if vectors.null_count:
            raise UserError(f"source '{self.source.name}' has {vectors.null_count} rows without values", self.source.where)
        if isinstance(vectors, pa.FixedSizeListArray):
            lengths_ok = vectors.type.list_size == self.width
            found = vectors.type.list_size
        else:
            lengths = vectors.value_lengths().to_numpy(zero_copy_only=False)
            lengths_ok = bool(np.all(lengths == self.width))
            found = int(lengths[lengths != self.width][0]) if not lengths_ok else self.width
        if not lengths_ok:
            raise UserError(
                f"source '{self.source.name}' has rows of {found} values but {self.width} names; names and values must match one to one",
                self.source.where,
            )
        flat = vectors.flatten().to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
        return flat.reshape(len(vectors), self.width)

    def urdf_values(self, raw: np.ndarray) -> np.ndarray:
        """(rows x width) raw source values -> (rows x joints) URDF values, recording limit statistics."""
        picked = raw[:, self.columns]
        values = picked * self.scale + self.offset
        below = self.lower - values
        above = values - self.upper
        excess = np.maximum(np.maximum(below, above), 0.0)
        nonfinite = ~np.isfinite(values)
        excess[nonfinite] = 0.0
        beyond = excess > self.slack
        within = (excess > 0.0) & ~beyond
        clamp_mask = within | (beyond & self.clamp_all)
        if clamp_mask.any():
            values = np.where(clamp_mask, np.clip(values, self.lower, self.upper), values)
        self._record(picked, excess, within, beyond, nonfinite)
        rows = len(raw)
        full = np.empty((rows, len(self.joint_names)), dtype=np.float64)
        count = len(self.columns)
        full[:, :count] = values
        full[:, count : count + len(self.held)] = self.held
        for target, driver, multiplier, offset in self.mimic_plan:
            full[:, target] = full[:, driver] * multiplier + offset
        return full

    def _record(self, picked: np.ndarray, excess: np.ndarray, within: np.ndarray, beyond: np.ndarray, nonfinite: np.ndarray) -> None:
        within_counts = within.sum(axis=0)
        beyond_counts = beyond.sum(axis=0)
        nonfinite_counts = nonfinite.sum(axis=0)
        within_excess = np.where(within, excess, -1.0)
        beyond_excess = np.where(beyond, excess, -1.0)
        within_arg = within_excess.argmax(axis=0) if len(picked) else np.zeros(len(self.columns), dtype=np.intp)
        beyond_arg = beyond_excess.argmax(axis=0) if len(picked) else np.zeros(len(self.columns), dtype=np.intp)
        with self._lock:
            self.stats.rows += len(picked)
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
                stats.nonfinite_rows += int(nonfinite_counts[i])

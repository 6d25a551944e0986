"""The `qa:` section compiled: every threshold of the dataset checks in SI units (rad, m, s), with the defaults
docs/qa.md justifies, and the fixed vocabulary of flags."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

QaFlag = Literal["spike", "static", "length_outlier", "timestamp_gap", "timestamp_order", "calibration_bias", "limits", "nan"]
QA_FLAGS: tuple[QaFlag, ...] = (
    "spike",
    "static",
    "length_outlier",
    "timestamp_gap",
    "timestamp_order",
    "calibration_bias",
    "limits",
    "nan",
)


@dataclass(frozen=True)
class ByKind:
    """One threshold by joint kind, in URDF units (rad..., m...), with the text the config wrote (for reports)."""

    angle: float
    length: float
    text: str

    def for_joint(self, angular: bool) -> float:
        return self.angle if angular else self.length


@dataclass(frozen=True)
class QaPlan:
    """The thresholds of `qa:`, SI units. The defaults flag, on 30 fps teleoperation data with 0.05 deg of sensor noise,
    a one-frame 40 deg jump, a still episode, one 3x the median length, 4 dropped frames and a backwards timestamp,
    and nothing on clean data (tests/execute/test_qa_metrics.py plants each)."""

    # a row is still when its per-step |velocity| is below this (the noise above makes ~2 deg/s at 30 fps)
    static_velocity: ByKind = ByKind(math.radians(5.0), 0.005, "{angle: 5 deg/s, length: 5 mm/s}")
    static_share: float = 0.95  # `static`: every joint still on at least this share of the rows
    spike_factor: float = 20.0  # `spike`: max |jerk| above this times the dataset's median p95 |jerk| of the joint
    spike_jerk: ByKind | None = None  # `spike` also above this absolute |jerk| (rad/s^3, m/s^3); None: no bound
    gap_seconds: float | None = None  # `timestamp_gap`: a step above this (s); None: gap_steps times the nominal step
    gap_steps: float = 2.5  # a step above this many nominal steps (1/fps, else the median of the first steps)
    length_iqr: float = 3.0  # `length_outlier`: rows beyond the quartiles by this many IQRs
    bias: ByKind = ByKind(math.radians(2.0), 0.002, "{angle: 2 deg, length: 2 mm}")  # `calibration_bias`: |mean| beyond
    fail_on: tuple[QaFlag, ...] = ()  # the flags that fail `qa` (exit 1)

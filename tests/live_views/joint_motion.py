"""The joint motion the test Foxglove server publishes, a function of the message index k alone, so a test recomputes
every value, stamp and name order it should receive (and tells the two runs of a restarted server apart by k)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

NAMES = ("shoulder", "elbow", "wrist")
LOWER, UPPER = -1.5, 2.0
START_NS = 1_700_000_000_000_000_000  # header stamp of message 0
LOG_DELAY_NS = 1_000  # a message's log time (its Foxglove timestamp) is its header stamp plus this


def values(k: int, names: Sequence[str], lower: float = LOWER, upper: float = UPPER) -> np.ndarray:
    """One value per name (in `names`' order) for message k, strictly within [lower, upper], each joint its own
    phase and speed."""
    index = np.arange(len(names), dtype=np.float64)
    middle, half = (lower + upper) / 2, (upper - lower) / 2
    return middle + 0.9 * half * np.sin(0.01 * k * (index + 1) + index)


def order(k: int, count: int) -> np.ndarray:
    """The order message k lists the joints in: shuffled, the same for the same k."""
    return np.random.default_rng(k).permutation(count)


def stamp_ns(k: int, period_ns: int, start_ns: int = START_NS) -> int:
    return start_ns + k * period_ns


def index_of(header_ns: int, period_ns: int, start_ns: int = START_NS) -> int:
    """The k whose stamp this is (a test's inverse of stamp_ns)."""
    k, rest = divmod(header_ns - start_ns, period_ns)
    assert rest == 0, f"{header_ns} is no stamp of the test motion"
    return k


def message(
    k: int, names: Sequence[str], period_ns: int, start_ns: int = START_NS, lower: float = LOWER, upper: float = UPPER
) -> dict[str, Any]:
    """The sensor_msgs/msg/JointState fields of message k, as the CDR encoder takes them."""
    sec, nanosec = divmod(stamp_ns(k, period_ns, start_ns), 1_000_000_000)
    shuffled, positions = order(k, len(names)), values(k, names, lower, upper)
    return {
        "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": ""},
        "name": [names[i] for i in shuffled],
        "position": [float(positions[i]) for i in shuffled],
        "velocity": [],
        "effort": [],
    }

"""The motion tests/live_views/mcap_appender.py writes: every field a function of the message index k (and a seed, so a
restarted recorder's file is told from the first), so a test recomputes what it must receive."""

from __future__ import annotations

import math
import random
from typing import Any

TOPIC = "/joint_states"
JOINTS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "gripper")
START_NS = 1_700_000_000_123_456_789
PERIOD_NS = 10_000_000  # header stamps 10 ms apart, whatever rate the appender writes at
LOG_DELAY_NS = 3_000_000  # log time = stamp + 3 ms, publish time = stamp + 1 ms
PUBLISH_DELAY_NS = 1_000_000


def header_ns(k: int, seed: int = 0) -> int:
    return START_NS + seed * 1_000_000_000_000 + k * PERIOD_NS


def log_time_ns(k: int, seed: int = 0) -> int:
    return header_ns(k, seed) + LOG_DELAY_NS


def publish_time_ns(k: int, seed: int = 0) -> int:
    return header_ns(k, seed) + PUBLISH_DELAY_NS


def names(k: int, seed: int = 0) -> tuple[str, ...]:
    """The joints in a shuffled order, a different one per message (as some drivers publish them)."""
    order = list(JOINTS)
    random.Random(seed * 1_000_003 + k).shuffle(order)
    return tuple(order)


def position(joint: str, k: int, seed: int = 0) -> float:
    return math.sin(0.05 * k + 0.7 * JOINTS.index(joint)) + 10.0 * seed


def positions(k: int, seed: int = 0) -> dict[str, float]:
    return {joint: position(joint, k, seed) for joint in JOINTS}


def message(k: int, seed: int = 0) -> dict[str, Any]:
    """The JointState message k, as the MCAP ROS 2 encoder takes it."""
    stamp = header_ns(k, seed)
    order = names(k, seed)
    return {
        "header": {"stamp": {"sec": stamp // 1_000_000_000, "nanosec": stamp % 1_000_000_000}, "frame_id": "base"},
        "name": list(order),
        "position": [position(joint, k, seed) for joint in order],
        "velocity": [],
        "effort": [],
    }

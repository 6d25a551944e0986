"""Small rotation helpers in URDF conventions (fixed-axis roll, pitch, yaw)."""

from __future__ import annotations

import math


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """URDF rpy (R = Rz(yaw) Ry(pitch) Rx(roll)) as a quaternion x, y, z, w."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def normalized_quaternion(q: tuple[float, ...]) -> tuple[float, float, float, float] | None:
    """Unit quaternion, or None when q is (numerically) zero and so no rotation at all."""
    norm = math.sqrt(sum(v * v for v in q))
    if norm < 1e-9 or not math.isfinite(norm):
        return None
    x, y, z, w = (v / norm for v in q)
    return (x, y, z, w)

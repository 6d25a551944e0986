"""Source units and their factor to URDF units (rad for angular joints, m for prismatic ones)."""

from __future__ import annotations

import math

FACTORS: dict[str, float] = {"rad": 1.0, "deg": math.pi / 180.0, "m": 1.0, "mm": 1e-3}
ANGULAR_UNITS = ("rad", "deg")
LINEAR_UNITS = ("m", "mm")


def urdf_unit(angular: bool) -> str:
    return "rad" if angular else "m"


def fits(unit: str, angular: bool) -> bool:
    return unit in (ANGULAR_UNITS if angular else LINEAR_UNITS)

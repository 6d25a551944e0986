"""Source units and their factor to URDF units (rad for angular joints, m for prismatic ones).

A robot's `joints.unit` says the unit by joint kind: an angular unit (rad, deg) applies to revolute and continuous
joints only, a length unit (m, cm, mm) to prismatic joints only, `{angle: deg, length: mm}` gives both; a kind the
config does not name keeps the URDF's own unit. A map entry's own `unit` must fit its joint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

FACTORS: dict[str, float] = {"rad": 1.0, "deg": math.pi / 180.0, "m": 1.0, "cm": 1e-2, "mm": 1e-3}
ANGULAR_UNITS = ("rad", "deg")
LINEAR_UNITS = ("m", "cm", "mm")


def urdf_unit(angular: bool) -> str:
    return "rad" if angular else "m"


def fits(unit: str, angular: bool) -> bool:
    return unit in (ANGULAR_UNITS if angular else LINEAR_UNITS)


@dataclass(frozen=True)
class RobotUnits:
    """The unit of a robot's source values by joint kind, from `joints.unit` (omitted: the URDF's units)."""

    angle: str = "rad"
    length: str = "m"
    given: str | None = None  # the single unit the config wrote, when it wrote one (for messages)

    def for_joint(self, angular: bool) -> str:
        return self.angle if angular else self.length


def robot_units(spec: Any) -> RobotUnits:
    """`joints.unit` as the schema allows it: absent, one unit (applies to its own kind only), or {angle, length}."""
    if spec is None:
        return RobotUnits()
    if isinstance(spec, str):
        return RobotUnits(angle=spec, given=spec) if spec in ANGULAR_UNITS else RobotUnits(length=spec, given=spec)
    return RobotUnits(angle=spec.get("angle", "rad"), length=spec.get("length", "m"))

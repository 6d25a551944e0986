"""Trails: the path of a chosen link in a chosen frame over a time window, drawn as a line or points that follow
the robot in the viewer (`trails:` in the config; compiled by `compile/trails.py`, drawn by `execute/trail_stream.py`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..errors import Where
from .robot_plans import EdgePlan

TrailStyle = Literal["line", "points"]
WindowUnit = Literal["s", "rows"]


@dataclass(frozen=True)
class TrailPlan:
    """One trail: where `link` of robot `robot` is in `frame` at every row its source drives, from the same joint
    values as the robot's FK. The path from `frame` down to the link is `edges` (static calibration edges, top down,
    ending at the robot's root link; empty when `frame` is a link of the robot itself) then the URDF joints from
    `start_link` down to `link`."""

    robot: str  # the robot's key
    link: str  # the URDF link, unprefixed
    frame: str  # the frame the positions are in, as the frame graph names it (prefix included)
    start_link: str  # the URDF link (unprefixed) the joint chain starts from: the robot's root link, or `frame`'s link
    edges: tuple[EdgePlan, ...]  # static edges from `frame` down to the robot's root link, top down
    entity: str  # "<entity_path_prefix>/trails/<link>"
    style: TrailStyle
    color: tuple[int, int, int, int] | None  # RGBA 0..255; None: the viewer's colour for the entity
    window: float | None  # the visible span before the time cursor; None: from the recording's start
    window_unit: WindowUnit  # seconds on time timelines, rows on sequence timelines
    timelines: tuple[str, ...]  # the timelines the window applies to (the trail's source's of that kind)
    where: Where

    @property
    def label(self) -> str:
        return f"trail of {self.robot}'s {self.link} in {self.frame}"

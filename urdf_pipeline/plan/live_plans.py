"""The plan of a live view, beside `Plan`: the sources a live view reads (`LiveSource`) and `LivePlan`."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import UserError, Where
from .robot_plans import RobotPlan
from .scene_plans import ScenePlan

DEFAULT_TIMELINE = "time"  # the live timeline of a source that is not a ROS topic: a timestamp, the push's time


@dataclass(frozen=True)
class LiveSource:
    """A config source as a live view reads it: its value names, and for an MCAP source the topic and which of a
    message's times places it (the timeline a run of the same bag would use)."""

    name: str
    kind: str  # the config's kind: parquet, lerobot, mcap, ...
    names: tuple[str, ...]
    where: Where
    topic: str | None = None  # mcap sources: the topic a live feed subscribes to
    stamp: str = "header"  # mcap sources: header, log_time or publish_time
    timeline: str = DEFAULT_TIMELINE


@dataclass(frozen=True)
class LiveSourceSpec:
    """What the config alone says of a source a live view reads; `names` None when only data or a stream holds them."""

    name: str
    kind: str
    names: tuple[str, ...] | None
    where: Where
    topic: str | None
    stamp: str
    timeline: str  # a run's timeline of the source (an MCAP topic's), else DEFAULT_TIMELINE

    def with_names(self, names: tuple[str, ...]) -> LiveSource:
        return LiveSource(self.name, self.kind, names, self.where, self.topic, self.stamp, self.timeline)


@dataclass(frozen=True)
class LivePlan(ScenePlan):
    """The config for live views, frozen: what `LiveView` applies to each sample. No segments, no outputs: its
    samples come from a control loop or a robot's stream."""

    application_id: str = ""
    sources: tuple[LiveSource, ...] = ()

    def source_named(self, name: str) -> LiveSource:
        return next(source for source in self.sources if source.name == name)

    def robot_named(self, key: str | None) -> RobotPlan:
        """The robot `key` names; without one, the only robot driven by a source (several: an error listing them)."""
        driven = [robot for robot in self.robots if robot.source is not None]
        if key is None and len(driven) == 1:
            return driven[0]
        for robot in self.robots:
            if robot.key == key:
                return robot
        keys = ", ".join(f"'{robot.key}'" for robot in driven) or "none"
        said = "no robot given" if key is None else f"no robot '{key}'"
        raise UserError(f"{said}; say which with robot= one of the robots driven by a source: {keys}", self.robots[0].where)

"""The frozen, typed plan: everything decided before any joint value is read."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from .errors import Where

OnViolation = Literal["error", "clamp", "ignore"]
TimelineKind = Literal["sequence", "timestamp", "duration"]


@dataclass(frozen=True)
class IndexPlan:
    column: str
    kind: TimelineKind
    unit: str | None  # "s" | "ms" | "us" | "ns" for time kinds


@dataclass(frozen=True)
class ParquetSourcePlan:
    name: str
    path: Path
    column: str
    index: IndexPlan
    names: tuple[str, ...]
    where: Where


@dataclass(frozen=True)
class LeRobotSourcePlan:
    name: str
    root: Path
    feature: str
    episode: int
    names: tuple[str, ...]
    where: Where


SourcePlan = ParquetSourcePlan | LeRobotSourcePlan


@dataclass(frozen=True)
class JointChannel:
    """One source value driving one URDF joint: urdf = (raw * factor) * sign + offset."""

    joint: str
    source_name: str
    source_index: int
    source_unit: str
    factor: float
    sign: float
    offset: float
    lower: float | None  # URDF units; None when the joint has no limits
    upper: float | None
    slack: float  # URDF units
    where: Where

    def to_source_unit(self, urdf_value: float) -> float:
        return (urdf_value - self.offset) / (self.factor * self.sign)


@dataclass(frozen=True)
class MimicJoint:
    """A <mimic> joint: value = driver * multiplier + offset, computed by the pipeline (Rerun's FK does not)."""

    joint: str
    driver: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class HeldJoint:
    joint: str
    value: float  # URDF units


@dataclass(frozen=True)
class RobotPlan:
    key: str
    urdf_path: Path  # the URDF (or xacro) file the text came from
    urdf_text: str  # URDF text with every resolved mesh URI replaced by an absolute path
    urdf_origin: str  # "file robots/panda.urdf", "xacro ... args", "robot_descriptions NAME @ COMMIT: path"
    urdf_sha256: str  # of the URDF text before mesh paths were made absolute: equal across machines
    robot_name: str
    root_link: str
    links: tuple[str, ...]
    joint_links: tuple[tuple[str, str, str], ...]  # (joint, parent link, child link), unprefixed
    entity_path_prefix: str  # "/arm"
    frame_prefix: str
    keep_collisions: bool
    source: str
    channels: tuple[JointChannel, ...]
    holds: tuple[HeldJoint, ...]
    mimics: tuple[MimicJoint, ...]  # ordered so a driver is computed before its mimic
    on_violation: OnViolation
    where: Where

    @property
    def fk_entity(self) -> str:
        return f"{self.entity_path_prefix}/joint_transforms"

    @property
    def static_transform_entity(self) -> str:
        return f"{self.entity_path_prefix}/tf_static"

    @property
    def collision_filter(self) -> str:
        return f"{self.entity_path_prefix}/{self.robot_name}/collision_geometries/**"


@dataclass(frozen=True)
class EdgePlan:
    parent: str
    child: str
    translation: tuple[float, float, float]
    quaternion_xyzw: tuple[float, float, float, float]
    where: Where


@dataclass(frozen=True)
class OutputPlan:
    path: Path
    application_id: str
    recording_id: str
    where: Where


@dataclass(frozen=True)
class Plan:
    config_path: Path
    sources: tuple[SourcePlan, ...]
    robots: tuple[RobotPlan, ...]
    edges: tuple[EdgePlan, ...]
    root_frame: str
    output: OutputPlan

    def source(self, name: str) -> SourcePlan:
        return next(s for s in self.sources if s.name == name)

    def robots_for(self, source: str) -> tuple[RobotPlan, ...]:
        return tuple(r for r in self.robots if r.source == source)

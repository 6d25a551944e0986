"""A light URDF reader: the joints, links and mesh URIs the compile stage checks, without importing Rerun."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

MOVING_TYPES = ("revolute", "continuous", "prismatic")
ANGULAR_TYPES = ("revolute", "continuous")


@dataclass(frozen=True)
class Mimic:
    joint: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class Joint:
    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower: float | None
    upper: float | None
    mimic: Mimic | None

    @property
    def moving(self) -> bool:
        return self.type in MOVING_TYPES

    @property
    def angular(self) -> bool:
        return self.type in ANGULAR_TYPES

    @property
    def has_limits(self) -> bool:
        """Continuous joints have none; a revolute/prismatic joint with lower >= upper has no usable range."""
        return self.type != "continuous" and self.lower is not None and self.upper is not None and self.lower < self.upper


@dataclass(frozen=True)
class MeshRef:
    link: str
    uri: str
    kind: str  # "visual" | "collision"


@dataclass(frozen=True)
class UrdfModel:
    name: str
    links: tuple[str, ...]
    joints: tuple[Joint, ...]
    meshes: tuple[MeshRef, ...]
    root_link: str

    def joint(self, name: str) -> Joint | None:
        return next((j for j in self.joints if j.name == name), None)


class UrdfParseError(Exception):
    """The file is not a usable URDF; the caller turns it into a user error at the config line."""


def _floats(text: str | None, count: int, default: float) -> tuple[float, ...]:
    if not text:
        return (default,) * count
    values = tuple(float(v) for v in text.split())
    if len(values) != count:
        raise UrdfParseError(f"expected {count} numbers, got '{text}'")
    return values


def _optional_float(text: str | None) -> float | None:
    return None if text is None else float(text)


def parse_urdf_text(text: str, origin: str) -> UrdfModel:
    try:
        robot = ET.fromstring(text)
    except ET.ParseError as exc:
        raise UrdfParseError(f"{origin} is not valid XML: {exc}") from None
    if robot.tag != "robot":
        raise UrdfParseError(f"{origin}: root element is <{robot.tag}>, not <robot>")
    links = tuple(link.get("name", "") for link in robot.findall("link"))
    meshes: list[MeshRef] = []
    for link in robot.findall("link"):
        for kind in ("visual", "collision"):
            for element in link.findall(kind):
                for mesh in element.findall("geometry/mesh"):
                    meshes.append(MeshRef(link.get("name", ""), mesh.get("filename", ""), kind))
    joints: list[Joint] = []
    try:
        for element in robot.findall("joint"):
            origin_el = element.find("origin")
            limit_el = element.find("limit")
            mimic_el = element.find("mimic")
            axis_el = element.find("axis")
            joints.append(
                Joint(
                    name=element.get("name", ""),
                    type=element.get("type", ""),
                    parent=element.find("parent").get("link", ""),  # type: ignore[union-attr]
                    child=element.find("child").get("link", ""),  # type: ignore[union-attr]
                    xyz=_floats(origin_el.get("xyz") if origin_el is not None else None, 3, 0.0),  # type: ignore[arg-type]
                    rpy=_floats(origin_el.get("rpy") if origin_el is not None else None, 3, 0.0),  # type: ignore[arg-type]
                    axis=_floats(axis_el.get("xyz") if axis_el is not None else None, 3, 0.0) if axis_el is not None else (1.0, 0.0, 0.0),  # type: ignore[arg-type]
                    lower=_optional_float(limit_el.get("lower", "0")) if limit_el is not None else None,
                    upper=_optional_float(limit_el.get("upper", "0")) if limit_el is not None else None,
                    mimic=Mimic(
                        mimic_el.get("joint", ""),
                        float(mimic_el.get("multiplier", "1")),
                        float(mimic_el.get("offset", "0")),
                    )
                    if mimic_el is not None
                    else None,
                )
            )
    except (AttributeError, ValueError) as exc:
        raise UrdfParseError(f"{origin}: malformed <joint>: {exc}") from None
    children = {j.child for j in joints}
    roots = [link for link in links if link not in children]
    if len(roots) != 1:
        raise UrdfParseError(f"{origin}: expected one root link, found {len(roots)}: {', '.join(roots) or 'none'}")
    for joint in joints:
        if not math.isfinite(joint.lower or 0.0) or not math.isfinite(joint.upper or 0.0):
            raise UrdfParseError(f"{origin}: joint '{joint.name}' has a non-finite limit")
    return UrdfModel(robot.get("name", ""), links, tuple(joints), tuple(meshes), roots[0])


def read_urdf(path: Path) -> tuple[str, UrdfModel]:
    text = path.read_text(encoding="utf-8")
    return text, parse_urdf_text(text, str(path))

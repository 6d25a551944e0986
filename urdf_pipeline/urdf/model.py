"""A light URDF reader: the joints, links and mesh URIs the compile stage checks, without importing Rerun.

It reads a URDF as ROS does (urdfdom): the first of a repeated element counts, joint axes are normalised, and a
structure ROS refuses (a joint naming a link that does not exist, two parents for a link, duplicate names, a mimic
cycle) is refused here too, naming the joint or link, before it could surface later as a confusing frame-graph error.
Every check is linear in links and joints.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from ..errors import Hints, listing
from .xml_text import UrdfParseError, parse_root

MOVING_TYPES = ("revolute", "continuous", "prismatic")
ANGULAR_TYPES = ("revolute", "continuous")
JOINT_TYPES = (*MOVING_TYPES, "fixed", "floating", "planar")
# A decimal number as urdfdom reads it (no "inf", "nan", hex or "1_0", which Python's float() would take).
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


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
    axis: tuple[float, float, float]  # unit length, as ROS reads it (zero only for joints that do not use it)
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
        return self._by_name.get(name)

    @cached_property
    def _by_name(self) -> dict[str, Joint]:
        """Joints by name, made once: callers look up every mapped joint (linear, not quadratic, in a large robot)."""
        return {joint.name: joint for joint in self.joints}

    def below(self, link: str) -> set[str]:
        """`link` and every link under it."""
        return {found for found, _ in _walk(link, self.joints)}

    def depth(self) -> tuple[int, str]:
        """How many joints the deepest link is below the root link, and that link; linear in the joints."""
        return max(((level, link) for link, level in _walk(self.root_link, self.joints)), key=lambda deepest: deepest[0])

    def mimic_order(self) -> tuple[Joint, ...]:
        """The mimic joints, each after the joint it mimics when that is a mimic too; linear in the joints.
        (The model refuses mimic cycles, so every walk ends.)"""
        ordered: list[Joint] = []
        placed: set[str] = set()
        for joint in self.joints:
            path: list[Joint] = []
            current: Joint | None = joint
            while current is not None and current.mimic is not None and current.name not in placed:
                path.append(current)
                placed.add(current.name)
                current = self._by_name.get(current.mimic.joint)
            ordered += reversed(path)
        return tuple(ordered)


def _walk(root: str, joints: Iterable[Joint]) -> Iterator[tuple[str, int]]:
    """Each link below `root` (itself first) once, with how many joints below it is: depth first, linear in the joints."""
    children: dict[str, list[str]] = {}
    for joint in joints:
        children.setdefault(joint.parent, []).append(joint.child)
    seen, frontier = {root}, [(root, 0)]
    while frontier:
        link, level = frontier.pop()
        yield link, level
        for child in children.get(link, ()):
            if child not in seen:
                seen.add(child)
                frontier.append((child, level + 1))


class InvalidNumber(ValueError):
    """One malformed value, reported with the joint it belongs to."""


def number(text: str, label: str = "value") -> float:
    """A URDF number, read as urdfdom reads it; InvalidNumber (naming `label`, e.g. `<limit lower>`) otherwise."""
    if not _NUMBER.fullmatch(text.strip()):
        raise InvalidNumber(f"{label} '{text}' is not a number")
    return float(text)


def numbers(text: str | None, count: int, default: float, label: str = "value") -> tuple[float, ...]:
    """`count` space-separated numbers (an absent attribute gives the default); InvalidNumber otherwise."""
    if text is None:
        return (default,) * count
    parts = text.split()
    if len(parts) != count or not all(_NUMBER.fullmatch(part) for part in parts):
        raise InvalidNumber(f"{label} '{text}' is not {count} numbers")
    return tuple(float(part) for part in parts)


def unit_vector(vector: tuple[float, ...]) -> tuple[float, float, float] | None:
    """The vector scaled to length 1 (URDF axis semantics); None for the zero vector."""
    norm = math.sqrt(sum(v * v for v in vector))
    if norm == 0.0:
        return None
    return (vector[0] / norm, vector[1] / norm, vector[2] / norm)


@dataclass
class _Problems:
    """Messages `ORIGIN:LINE: message`, the line of the element at fault when the text is the file itself."""

    origin: str
    lines: dict[int, int] | None
    messages: list[str] = field(default_factory=list)
    hint: Hints = field(default_factory=Hints)  # "did you mean", for the first problems of the file

    def add(self, message: str, element: ET.Element | None = None) -> None:
        line = self.lines.get(id(element)) if self.lines is not None and element is not None else None
        self.messages.append(f"{self.origin}:{line}: {message}" if line else f"{self.origin}: {message}")


def _joint(element: ET.Element, problems: _Problems) -> Joint | None:
    name, kind = element.get("name", ""), element.get("type", "")
    if kind not in JOINT_TYPES:
        problems.add(f"joint '{name}' has type '{kind}'; a URDF joint is one of {', '.join(JOINT_TYPES)}", element)
        return None
    links: dict[str, str] = {}
    for end in ("parent", "child"):
        found = element.find(end)
        links[end] = "" if found is None else found.get("link", "")
        if not links[end]:
            problems.add(f"joint '{name}' has no <{end} link=\"...\"/>", element)
    origin_el, axis_el, limit_el, mimic_el = (element.find(tag) for tag in ("origin", "axis", "limit", "mimic"))
    try:
        xyz = numbers(None if origin_el is None else origin_el.get("xyz"), 3, 0.0, "<origin xyz>")
        rpy = numbers(None if origin_el is None else origin_el.get("rpy"), 3, 0.0, "<origin rpy>")
        # urdfdom: no <axis> is 1 0 0; an <axis> without xyz is 0 0 0.
        raw_axis = (1.0, 0.0, 0.0) if axis_el is None else numbers(axis_el.get("xyz", "0 0 0"), 3, 0.0, "<axis xyz>")
        lower = upper = None
        if limit_el is not None:
            lower = number(limit_el.get("lower", "0"), "<limit lower>")
            upper = number(limit_el.get("upper", "0"), "<limit upper>")
        mimic = None
        if mimic_el is not None and kind in MOVING_TYPES:  # a <mimic> on a joint that cannot move changes nothing
            multiplier = number(mimic_el.get("multiplier", "1"), "<mimic multiplier>")
            mimic = Mimic(mimic_el.get("joint", ""), multiplier, number(mimic_el.get("offset", "0"), "<mimic offset>"))
    except InvalidNumber as exc:
        problems.add(f"joint '{name}': {exc}", element)
        return None
    axis = unit_vector(raw_axis)
    if axis is None and kind in MOVING_TYPES:
        no_xyz = axis_el is not None and "xyz" not in axis_el.attrib
        shown = "has an <axis> without xyz (ROS reads it as 0 0 0)" if no_xyz else "has axis 0 0 0"
        problems.add(f"joint '{name}' ({kind}) {shown}; give <axis xyz=\"...\"/> the direction it moves along", element)
        return None
    if mimic is not None and not mimic.joint:
        problems.add(f"joint '{name}' has a <mimic> without joint=\"...\"", element)
        return None
    if not all(links.values()):
        return None
    return Joint(name, kind, links["parent"], links["child"], xyz, rpy, axis or (0.0, 0.0, 0.0), lower, upper, mimic)  # type: ignore[arg-type]


def _unique(kind: str, elements: list[ET.Element], problems: _Problems) -> None:
    seen: set[str] = set()
    for element in elements:
        name = element.get("name", "")
        if not name:
            problems.add(f'a <{kind}> has no name="..."', element)
        elif name in seen:
            problems.add(f"two <{kind}> elements are named '{name}'; URDF {kind} names must be unique", element)
        seen.add(name)


def _check_tree(joints: dict[str, tuple[Joint, ET.Element]], links: tuple[str, ...], problems: _Problems) -> None:
    known = set(links)
    ordered = sorted(known)
    parent_joint: dict[str, Joint] = {}
    for joint, element in joints.values():
        for end, link in (("parent", joint.parent), ("child", joint.child)):
            if link not in known:
                problems.add(
                    f"joint '{joint.name}' names {end} link '{link}', which the URDF does not define{problems.hint(link, ordered)}; "
                    f'fix the joint\'s <{end} link="..."/> or add <link name="{link}"/>',
                    element,
                )
        if joint.parent == joint.child:
            problems.add(f"joint '{joint.name}' connects link '{joint.child}' to itself", element)
        first = parent_joint.get(joint.child)
        if first is not None:
            problems.add(
                f"link '{joint.child}' is the child of two joints, '{first.name}' and '{joint.name}'; a link has exactly one parent joint",
                element,
            )
        parent_joint.setdefault(joint.child, joint)


def _check_mimics(joints: dict[str, tuple[Joint, ET.Element]], declared: set[str], problems: _Problems) -> None:
    """`declared`: every joint name in the file, those already refused included (no second error for them)."""
    by_name = {name: joint for name, (joint, _) in joints.items()}
    ordered = sorted(by_name)
    for joint, element in joints.values():
        if joint.mimic is None or (joint.mimic.joint in declared and joint.mimic.joint not in by_name):
            continue
        driver = by_name.get(joint.mimic.joint)
        if driver is None:
            hint = problems.hint(joint.mimic.joint, ordered)
            problems.add(f"joint '{joint.name}' mimics '{joint.mimic.joint}', which the URDF lacks{hint}", element)
        elif not driver.moving:
            problems.add(f"joint '{joint.name}' mimics '{driver.name}', a {driver.type} joint that never moves", element)
    done: set[str] = set()  # joints whose walk along their drivers ended: each joint is walked once
    for joint, element in joints.values():
        path: list[str] = []
        on_path: set[str] = set()
        current: Joint | None = joint
        while current is not None and current.name not in done and current.name not in on_path:
            path.append(current.name)
            on_path.add(current.name)
            current = by_name.get(current.mimic.joint) if current.mimic is not None else None
        if current is not None and current.name in on_path:
            cycle = path[path.index(current.name) :]
            problems.add(f"joints mimic each other in a cycle: {' -> '.join([*cycle, cycle[0]])}; one of them must be driven", element)
        done.update(path)


def _root(joints: list[Joint], links: tuple[str, ...], origin: str) -> str:
    if not links:
        raise UrdfParseError(f"{origin}: the URDF defines no <link>")
    children = {j.child for j in joints}
    roots = [link for link in links if link not in children]
    if len(roots) == 1:
        below = {link for link, _ in _walk(roots[0], joints)}
        cut_off = [link for link in links if link not in below]
        if cut_off:
            raise UrdfParseError(f"{origin}: links {listing(cut_off)} form a cycle of joints, cut off from root link '{roots[0]}'")
        return roots[0]
    if not roots:
        raise UrdfParseError(f"{origin}: every link has a parent joint, so the joints form a cycle and there is no root link")
    raise UrdfParseError(
        f"{origin}: expected one root link, found {len(roots)}: {listing(roots)}; connect them with joints so one link is the root"
    )


_MODELS: dict[tuple[str, bool], UrdfModel] = {}  # the last few texts parsed: plan and diff read the compiled text again
_KEEP_MODELS = 16


def parse_urdf_text(text: str, origin: str, source_lines: bool = True) -> UrdfModel:
    """The model of a URDF text; UrdfParseError with one message per problem, each `origin:LINE:` when `source_lines`
    (the text is the file itself, not expanded from xacro). A text parsed before is not parsed again."""
    model = _MODELS.get((text, source_lines))
    if model is None:
        model, _ = parse_urdf(text, origin, source_lines)
    return model


def parse_urdf(text: str, origin: str, source_lines: bool = True) -> tuple[UrdfModel, ET.Element]:
    """`parse_urdf_text`, also giving the parsed XML root (for repairs: the text is parsed once)."""
    robot, lines = parse_root(text, origin, source_lines)
    problems = _Problems(origin, lines if source_lines else None)
    link_elements = robot.findall("link")
    links = tuple(link.get("name", "") for link in link_elements)
    _unique("link", link_elements, problems)
    meshes: list[MeshRef] = []
    for link in link_elements:
        for kind in ("visual", "collision"):
            for element in link.findall(kind):
                for mesh in element.findall("geometry/mesh"):
                    meshes.append(MeshRef(link.get("name", ""), mesh.get("filename", ""), kind))
    elements = robot.findall("joint")
    _unique("joint", elements, problems)
    joints: dict[str, tuple[Joint, ET.Element]] = {}
    for element in elements:
        joint = _joint(element, problems)
        if joint is not None:
            joints.setdefault(joint.name, (joint, element))
    _check_tree(joints, links, problems)
    _check_mimics(joints, {e.get("name", "") for e in elements}, problems)
    if problems.messages:
        raise UrdfParseError(*problems.messages)
    model_joints = [joint for joint, _ in joints.values()]
    model = UrdfModel(robot.get("name", ""), links, tuple(model_joints), tuple(meshes), _root(model_joints, links, origin))
    if len(_MODELS) >= _KEEP_MODELS:
        _MODELS.pop(next(iter(_MODELS)))
    _MODELS[(text, source_lines)] = model
    return model, robot


def read_urdf(path: Path) -> tuple[str, UrdfModel]:
    text = path.read_text(encoding="utf-8")
    return text, parse_urdf_text(text, str(path))

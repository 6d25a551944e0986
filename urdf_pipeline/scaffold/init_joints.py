"""The `joints:` block `init` writes: the robot's unit, the map with a comment per joint saying how far to trust it,
the source names left out (`ignore`), the joints the data lacks (`hold`), and notes on joints no map drives."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..sources import SourceDescription
from ..urdf import Joint, UrdfModel
from .init_units import SampledUnits
from .name_match import Match
from .yaml_writer import Block, Seq, number


@dataclass(frozen=True)
class Source:
    """The source the joints are read from, as the block names and judges it."""

    key: str  # its key under `sources:`
    description: SourceDescription
    stub: bool  # no --source: a stub to fill in, so no match is a guess


def joint_summary(joint: Joint) -> str:
    unit = "rad" if joint.angular else "m"
    if joint.type == "continuous":
        return "continuous, no limits (rad)"
    if joint.has_limits:
        return f"{joint.type}, {number(joint.lower or 0.0)} .. {number(joint.upper or 0.0)} {unit}"
    return f"{joint.type}, no usable limits ({unit})"


def hold_value(joint: Joint) -> float:
    """0.0, or the middle of the limits when 0 is outside them."""
    if not joint.has_limits or (joint.lower or 0.0) <= 0.0 <= (joint.upper or 0.0):
        return 0.0
    lower, upper = float(joint.lower or 0.0), float(joint.upper or 0.0)
    middle = round((lower + upper) / 2, 6)
    return middle if lower <= middle <= upper else (lower + upper) / 2


def drivable(model: UrdfModel) -> list[Joint]:
    """The joints the data drives: moving ones, except mimic joints (computed from the joint they follow)."""
    return [j for j in model.joints if j.moving and j.mimic is None]


def joints_block(model: UrdfModel, source: Source, names: list[str], matches: list[Match], units: SampledUnits | None) -> Block:
    """`joints:`: source and unit, the map, what the data leaves out (ignore, hold), notes on joints the map cannot drive."""
    driven = drivable(model)
    angular = any(j.angular for j in driven)
    unit, unit_comment = _robot_unit(angular, units)
    joints = Block()
    joints.add("source", source.key)
    joints.add("unit", unit, unit_comment)
    mapping = _joint_map(model, source, matches, unit, angular, units)
    joints.add("map", mapping, "source name: URDF joint (add sign, offset, unit per entry when needed)")
    ignored = _ignored(source.description, names, matches)
    if ignored.items:
        joints.add("ignore", ignored, "source names deliberately unused")
    held = _held(driven, matches)
    if held.items:
        joints.add("hold", held, "URDF joints the data lacks -> a fixed value in URDF units")
    for note in _undriven_notes(model):
        joints.note(note)
    return joints


def _robot_unit(angular: bool, units: SampledUnits | None) -> tuple[str, str]:
    """The robot's unit (its revolute joints' if any) and why: what most sampled joints point to, else the URDF's."""
    if units is not None and (sampled := units.robot_unit(angular)):
        return sampled
    other = "prismatic joints say theirs (m | mm) in their entry" if angular else "all joints are prismatic"
    return "rad" if angular else "m", f"review: the unit of the source values ({'rad | deg' if angular else 'm | mm'}); {other}"


def _joint_map(model: UrdfModel, source: Source, matches: list[Match], unit: str, angular: bool, units: SampledUnits | None) -> Block:
    """`map:`: a bare joint name where the robot's unit fits it, else `{joint, unit}`; each comment says why, to review."""
    by_name = {j.name: j for j in model.joints}
    length = units.robot_unit(False) if units is not None and angular else None
    mapping = Block()
    for match in matches:
        joint = by_name[match.joint]
        choice = units.joints.get(match.joint) if units is not None else None
        kind_unit = unit if joint.angular == angular else (length[0] if length else "m")
        own = choice.unit if choice is not None else kind_unit
        value: Any = match.joint if own == unit and joint.angular == angular else {"joint": match.joint, "unit": own}
        comment = _match_comment(match, joint, source.description, source.stub)
        mapping.add(match.source_name, value, comment + (f"; {choice.reason}" if choice is not None else ""))
    return mapping


def _match_comment(match: Match, joint: Joint, source: SourceDescription, stub: bool) -> str:
    """How far to trust the match (by name, by position, or surely wrong), and the joint's limits to check it against."""
    if stub:
        return joint_summary(joint)
    if source.names is None:
        return f"review: matched by position; {joint_summary(joint)}"
    if match.score == 0.0:
        return f"TODO: no source name resembles a joint name: matched by position, surely wrong; {joint_summary(joint)}"
    return f"review: matched by name (score {match.score:.2f}); {joint_summary(joint)}"


def _ignored(source: SourceDescription, names: list[str], matches: list[Match]) -> Seq:
    """`ignore:`, the source names no joint matched, each a TODO: leaving data unused must be a decision."""
    matched = {m.source_name for m in matches}
    why = "a value beyond the URDF's joints" if source.names is None else "no URDF joint resembles it"
    return Seq([(n, f"TODO: {why}: map it, or keep it ignored") for n in names if n not in matched])


def _held(drivable: list[Joint], matches: list[Match]) -> Block:
    """`hold:`, the joints no source name matched, each a TODO at a value within its limits (none may be left undriven)."""
    matched = {m.joint for m in matches}
    hold = Block()
    for joint in (j for j in drivable if j.name not in matched):
        value = hold_value(joint)
        hold.add(joint.name, value, f"TODO: not in the data, held at {number(value)}; {joint_summary(joint)}")
    return hold


def _undriven_notes(model: UrdfModel) -> list[str]:
    """What moves without the map, so that none surprises: mimic joints (computed), floating and planar ones (static)."""
    mimics = [
        f"mimic (computed by the pipeline, not mapped): {j.name} = {m.joint} * {number(m.multiplier)} + {number(m.offset)}"
        for j in model.joints
        if (m := j.mimic) is not None
    ]
    free = [
        f"{j.type} joint {j.name} ({j.parent} -> {j.child}) is not driven: a static identity unless "
        "a temporal edge (edges: - {parent, child, source, translation, quaternion_xyzw}) drives it"
        for j in model.joints
        if j.type in ("floating", "planar")
    ]
    return mimics + free

"""Decide, before reading any value, which source value drives which URDF joint and how.

Every moving URDF joint is covered exactly once (map, hold or <mimic>); every source name is mapped or ignored.
Conversion order: unit conversion, then sign, then offset: urdf = (raw * factor) * sign + offset.
"""

from __future__ import annotations

import difflib
from typing import Any

from .document import Document
from .errors import Problems
from .plan import HeldJoint, JointChannel, MimicJoint, OnViolation
from .units import FACTORS, fits, urdf_unit
from .urdf_model import UrdfModel


def _hint(name: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(name, choices, n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def compile_joints(
    robot_key: str,
    joints_spec: dict[str, Any],
    names: tuple[str, ...],
    model: UrdfModel,
    document: Document,
    problems: Problems,
) -> tuple[tuple[JointChannel, ...], tuple[HeldJoint, ...], tuple[MimicJoint, ...], OnViolation]:
    here = ("robots", robot_key, "joints")
    source = joints_spec["source"]
    default_unit = joints_spec.get("unit", "rad")
    limits = joints_spec.get("limits", {})
    slack_source = float(limits.get("slack", 0.0))
    on_violation: OnViolation = limits.get("on_violation", "error")
    moving = [j.name for j in model.joints if j.moving]
    all_joints = [j.name for j in model.joints]
    mimic_joints = {j.name for j in model.joints if j.mimic is not None}

    channels: list[JointChannel] = []
    covered: dict[str, str] = {}  # joint -> how ("map entry 'j1'", "hold")
    attempted: set[str] = set()  # joints named by a rejected entry: already reported, not "not driven" too
    for source_name, entry in joints_spec["map"].items():
        where = document.where(*here, "map", source_name)
        spec = {"joint": entry} if isinstance(entry, str) else entry
        joint_name = spec["joint"]
        attempted.add(joint_name)
        if source_name not in names:
            problems.add(
                f"'{source_name}' is not a name of source '{source}'{_hint(source_name, list(names))}; its names are: {', '.join(names)}",
                where,
            )
            continue
        joint = model.joint(joint_name)
        if joint is None:
            problems.add(f"URDF '{model.name}' has no joint '{joint_name}'{_hint(joint_name, all_joints)}", where)
            continue
        if not joint.moving:
            problems.add(f"joint '{joint_name}' is {joint.type}; only revolute, continuous and prismatic joints can be driven", where)
            continue
        if joint.mimic is not None:
            problems.add(f"joint '{joint_name}' is a <mimic> of '{joint.mimic.joint}' and is computed from it; remove it from map", where)
            continue
        if joint_name in covered:
            problems.add(f"joint '{joint_name}' is driven twice: by {covered[joint_name]} and by map entry '{source_name}'", where)
            continue
        unit = spec.get("unit", default_unit)
        if not fits(unit, joint.angular):
            origin = "its map entry" if "unit" in spec else "joints.unit"
            problems.add(
                f"joint '{joint_name}' is {joint.type} (URDF unit {urdf_unit(joint.angular)}) but its source unit is {unit} (from {origin}); "
                f"set unit: {'rad or deg' if joint.angular else 'm or mm'} on this entry",
                where,
            )
            continue
        covered[joint_name] = f"map entry '{source_name}'"
        factor = FACTORS[unit]
        channels.append(
            JointChannel(
                joint=joint_name,
                source_name=source_name,
                source_index=names.index(source_name),
                source_unit=unit,
                factor=factor,
                sign=float(spec.get("sign", 1)),
                offset=float(spec.get("offset", 0.0)),
                lower=joint.lower if joint.has_limits else None,
                upper=joint.upper if joint.has_limits else None,
                slack=slack_source * factor,
                where=where,
            )
        )

    holds: list[HeldJoint] = []
    for joint_name, value in joints_spec.get("hold", {}).items():
        where = document.where(*here, "hold", joint_name)
        joint = model.joint(joint_name)
        attempted.add(joint_name)
        if joint is None:
            problems.add(f"URDF '{model.name}' has no joint '{joint_name}'{_hint(joint_name, all_joints)}", where)
        elif not joint.moving:
            problems.add(f"joint '{joint_name}' is {joint.type}; only moving joints can be held", where)
        elif joint.mimic is not None:
            problems.add(f"joint '{joint_name}' is a <mimic> of '{joint.mimic.joint}' and is computed from it; remove it from hold", where)
        elif joint_name in covered:
            problems.add(f"joint '{joint_name}' is both held and driven by {covered[joint_name]}; keep one", where)
        elif joint.has_limits and not (joint.lower <= value <= joint.upper):  # type: ignore[operator]
            problems.add(
                f"hold value {value} for '{joint_name}' is outside its URDF limits [{joint.lower}, {joint.upper}] {urdf_unit(joint.angular)}",
                where,
            )
        else:
            covered[joint_name] = "hold"
            holds.append(HeldJoint(joint_name, float(value)))

    ignored = joints_spec.get("ignore", [])
    for index, name in enumerate(ignored):
        where = document.where(*here, "ignore", index)
        if name not in names:
            problems.add(f"ignored name '{name}' is not a name of source '{source}'{_hint(name, list(names))}", where)
        elif name in joints_spec["map"]:
            problems.add(f"'{name}' is both mapped and ignored; keep one", where)

    unused = [n for n in names if n not in joints_spec["map"] and n not in ignored]
    if unused:
        problems.add(
            f"source names neither mapped nor ignored: {', '.join(unused)}; map each to a URDF joint or list it under ignore",
            document.where(*here, "map"),
        )
    mimics = _order_mimics(model, mimic_joints)
    uncovered = [j for j in moving if j not in covered and j not in mimic_joints and j not in attempted]
    if uncovered:
        problems.add(
            f"URDF joints not driven by any source value: {', '.join(uncovered)}; add each to map, or to hold with a fixed value",
            document.where(*here, "map"),
        )
    return tuple(channels), tuple(holds), mimics, on_violation


def _order_mimics(model: UrdfModel, mimic_joints: set[str]) -> tuple[MimicJoint, ...]:
    """Mimic joints in dependency order (a mimic may follow another mimic)."""
    ordered: list[MimicJoint] = []
    done: set[str] = set()
    pending = [j for j in model.joints if j.name in mimic_joints]
    while pending:
        ready = [j for j in pending if j.mimic and (j.mimic.joint not in mimic_joints or j.mimic.joint in done)]
        if not ready:
            break  # a mimic cycle; reported by the caller's URDF checks
        for joint in ready:
            assert joint.mimic is not None
            ordered.append(MimicJoint(joint.name, joint.mimic.joint, joint.mimic.multiplier, joint.mimic.offset))
            done.add(joint.name)
        pending = [j for j in pending if j.name not in done]
    return tuple(ordered)

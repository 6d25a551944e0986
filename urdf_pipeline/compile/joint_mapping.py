"""Decide, before reading any value, which source value drives which URDF joint and how.

Every moving URDF joint is covered exactly once (map, hold or <mimic>); every source name is mapped or ignored.
Names None (`validate --no-data`, a source whose names only its data holds): the map's keys and `ignore` are not
checked against the source, everything about the URDF side is.
Conversion order: unit conversion, then sign, then offset: urdf = (raw * factor) * sign + offset. The unit of a
value is its entry's `unit`, else the robot's `joints.unit` for the joint's kind (units.robot_units).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ..errors import Hints, Where, listing, quoted
from ..errors import did_you_mean as _hint
from ..plan import HeldJoint, JointChannel, MimicJoint, OnViolation
from ..urdf import UrdfModel
from .context import UNKNOWN_INDEX, CompileContext
from .units import ANGULAR_UNITS, FACTORS, RobotUnits, fits, parse_slack, robot_units, urdf_unit


@dataclass(frozen=True)
class JointMapping:
    """How a robot's joints move: channels from source values, held joints, mimics in order, and the limit policy.
    The default is a scene's: nothing moves."""

    channels: tuple[JointChannel, ...] = ()
    holds: tuple[HeldJoint, ...] = ()
    mimics: tuple[MimicJoint, ...] = ()
    on_violation: OnViolation = "error"


@dataclass(frozen=True)
class _RobotJoints:
    """What every map entry of one robot shares: its URDF and the units of `joints.unit`."""

    model: UrdfModel
    units: RobotUnits


@dataclass(frozen=True)
class _MapEntry:
    """One `joints.map` entry whose source name exists: the value it reads and what it says about the joint(s)."""

    source_name: str
    source_index: int
    spec: dict[str, Any]  # the entry's mapping form: a bare joint name is {"joint": name}
    where: Where


def compile_joints(
    ctx: CompileContext, robot_key: str, joints_spec: dict[str, Any], names: tuple[str, ...] | None, model: UrdfModel
) -> JointMapping:
    problems = ctx.problems
    here = ("robots", robot_key, "joints")
    source = joints_spec["source"]
    limit_spec = joints_spec.get("limits", {})
    robot = _RobotJoints(model, robot_units(joints_spec.get("unit")))
    on_violation: OnViolation = limit_spec.get("on_violation", "error")
    moving = [j.name for j in model.joints if j.moving]
    all_joints = [j.name for j in model.joints]
    mimic_joints = {j.name for j in model.joints if j.mimic is not None}
    positions = {name: i for i, name in enumerate(names)} if names is not None else None  # linear in a wide source
    hint = Hints()

    channels: list[JointChannel] = []
    covered: dict[str, str] = {}  # joint -> how ("map entry 'j1'", "hold")
    attempted: set[str] = set()  # joints named by a rejected entry: already reported, not "not driven" too
    for source_name, written in joints_spec["map"].items():
        where = ctx.where(*here, "map", source_name)
        spec = {"joint": written} if isinstance(written, str) else written
        joint_names = spec["joint"] if isinstance(spec["joint"], list) else [spec["joint"]]
        attempted.update(joint_names)
        if names is not None and positions is not None and source_name not in positions:
            problems.add(
                f"'{source_name}' is not a name of source '{source}'{hint(source_name, names)}; its names are: {listing(names)}",
                where,
            )
            continue
        entry = _MapEntry(source_name, positions[source_name] if positions is not None else UNKNOWN_INDEX, spec, where)
        if not _corrections_consistent(ctx, entry):
            continue
        for joint_name in joint_names:
            if joint_name in covered:  # accepted for an earlier entry, so it exists and moves: the one thing wrong is this
                problems.add(f"joint '{joint_name}' is driven twice: by {covered[joint_name]} and by map entry '{source_name}'", where)
                continue
            channel = _channel(ctx, robot, entry, joint_name)
            if channel is not None:
                covered[joint_name] = f"map entry '{source_name}'"
                channels.append(channel)

    holds: list[HeldJoint] = []
    for joint_name, value in joints_spec.get("hold", {}).items():
        where = ctx.where(*here, "hold", joint_name)
        joint = model.joint(joint_name)
        attempted.add(joint_name)
        if joint is None:
            problems.add(f"URDF '{model.name}' has no joint '{joint_name}'{hint(joint_name, all_joints)}", where)
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

    ignored = [str(name) for name in joints_spec.get("ignore", [])]  # 7 and "7": a value named by its index
    for index, name in enumerate(ignored):
        where = ctx.where(*here, "ignore", index)
        if names is not None and positions is not None and name not in positions:
            problems.add(f"ignored name '{name}' is not a name of source '{source}'{hint(name, names)}", where)
        elif name in joints_spec["map"]:
            problems.add(f"'{name}' is both mapped and ignored; keep one", where)

    if robot.units.given is not None:
        _check_unit_applies(ctx, robot, joints_spec, ctx.where(*here, "unit"))
    ignored_set = set(ignored)
    unused = [n for n in names or () if n not in joints_spec["map"] and n not in ignored_set]
    if unused:
        problems.add(
            f"source names neither mapped nor ignored: {listing(unused)}; map each to a URDF joint or list it under ignore",
            ctx.where(*here, "map"),
        )
    channels = _with_slack(ctx, (*here, "limits", "slack"), model, limit_spec, channels)
    mimics = _order_mimics(model)
    uncovered = [j for j in moving if j not in covered and j not in mimic_joints and j not in attempted]
    if uncovered:
        problems.add(
            f"URDF joints not driven by any source value: {', '.join(uncovered)}; add each to map, or to hold with a fixed value",
            ctx.where(*here, "map"),
        )
    return JointMapping(tuple(channels), tuple(holds), mimics, on_violation)


def _corrections_consistent(ctx: CompileContext, entry: _MapEntry) -> bool:
    """source_range maps straight into URDF units, so it cannot be combined with the unit path's corrections."""
    spec, where, problems = entry.spec, entry.where, ctx.problems
    if "joint_range" in spec and "source_range" not in spec:
        problems.add("joint_range needs source_range (the source values mapped onto it)", where)
        return False
    if "source_range" in spec:
        mixed = [key for key in ("unit", "scale", "sign", "offset") if key in spec]
        if mixed:
            problems.add(
                f"source_range maps values straight onto the joint's range; remove {', '.join(mixed)} (write source_range: [max, min] to flip)",
                where,
            )
            return False
        low, high = spec["source_range"]
        if low == high:
            problems.add(f"source_range [{low}, {high}] is empty", where)
            return False
    return True


def _channel(ctx: CompileContext, robot: _RobotJoints, entry: _MapEntry, joint_name: str) -> JointChannel | None:
    """One (source value, URDF joint) pair, or None after reporting why it cannot be."""
    model, spec, where, problems = robot.model, entry.spec, entry.where, ctx.problems
    joint = model.joint(joint_name)
    if joint is None:
        problems.add(f"URDF '{model.name}' has no joint '{joint_name}'{_hint(joint_name, [j.name for j in model.joints])}", where)
        return None
    if not joint.moving:
        problems.add(f"joint '{joint_name}' is {joint.type}; only revolute, continuous and prismatic joints can be driven", where)
        return None
    if joint.mimic is not None:
        problems.add(f"joint '{joint_name}' is a <mimic> of '{joint.mimic.joint}' and is computed from it; remove it from map", where)
        return None
    limits = (float(joint.lower), float(joint.upper)) if joint.has_limits and joint.lower is not None and joint.upper is not None else None
    source_range = tuple(float(v) for v in spec["source_range"]) if "source_range" in spec else None
    target_range = tuple(float(v) for v in spec.get("joint_range", limits or ())) or None
    if source_range is not None and target_range is None:
        problems.add(
            f"joint '{joint_name}' has no URDF limits to map source_range onto; give joint_range: [low, high] in URDF units", where
        )
        return None
    unit = "source_range" if source_range is not None else spec.get("unit", robot.units.for_joint(joint.angular))
    if source_range is None and not fits(unit, joint.angular):  # only an entry's own unit can be of the other kind
        problems.add(
            f"joint '{joint_name}' is {joint.type} (URDF unit {urdf_unit(joint.angular)}) but its source unit is {unit} (from its map entry); "
            f"set unit: {'rad or deg' if joint.angular else 'm, cm or mm'} on this entry",
            where,
        )
        return None
    channel = JointChannel(
        joint=joint_name,
        source_name=entry.source_name,
        source_index=entry.source_index,
        source_unit=unit if source_range is None else "source units",
        factor=FACTORS.get(unit, 1.0),
        sign=float(spec.get("sign", 1)),
        offset=float(spec.get("offset", 0.0)),
        lower=limits[0] if limits else None,
        upper=limits[1] if limits else None,
        slack=0.0,
        where=where,
        scale=float(spec.get("scale", 1.0)),
        source_range=source_range,  # type: ignore[arg-type]
        target_range=target_range,  # type: ignore[arg-type]
    )
    wrap = spec.get("wrap")
    center = channel.to_source_unit((limits[0] + limits[1]) / 2) if limits else channel.to_source_unit(0.0)
    return replace(channel, wrap=float(wrap) if wrap else None, wrap_center=center)


def _with_slack(
    ctx: CompileContext, here: tuple[str, ...], model: UrdfModel, limit_spec: dict[str, Any], channels: list[JointChannel]
) -> list[JointChannel]:
    """limits.slack onto each channel, in URDF units by joint kind (units.parse_slack), so joints.unit cannot change it."""
    angular = {c.joint: bool(getattr(model.joint(c.joint), "angular", True)) for c in channels}
    written_units: dict[bool, list[str]] = {}
    for c in channels:
        if c.source_range is None:
            written_units.setdefault(angular[c.joint], []).append(c.source_unit)
    meant = {kind: max(units, key=units.count) for kind, units in written_units.items()}  # the most common, first on a tie
    for c in channels:  # a kind mapped only by source_range: its bare slack was in range units; name the URDF's
        meant.setdefault(angular[c.joint], urdf_unit(angular[c.joint]))
    slack, problems = parse_slack(limit_spec.get("slack"), meant)
    for problem in problems:
        ctx.problems.add(problem.message, ctx.where(*here, *problem.path))
    kind = slack.single
    if kind is not None and channels and not any(angular[c.joint] == kind for c in channels):
        ctx.problems.add(
            f"slack {quoted(limit_spec['slack'])} applies to {'revolute and continuous' if kind else 'prismatic'} joints only, and no mapped "
            f"joint is one: it would change nothing; write it in {'m, cm or mm' if kind else 'rad or deg'}, or as {{angle: ..., length: ...}}",
            ctx.where(*here),
        )
    return [replace(c, slack=slack.for_joint(angular[c.joint]), slack_written=slack.written(angular[c.joint])) for c in channels]


def _check_unit_applies(ctx: CompileContext, robot: _RobotJoints, joints_spec: dict[str, Any], where: Where) -> None:
    """A single joints.unit applies to one joint kind only; naming a kind no mapped joint has is a mistake, not a no-op."""
    given, model = robot.units.given, robot.model
    assert given is not None  # called only when joints.unit is one unit
    angular = given in ANGULAR_UNITS
    for entry in joints_spec["map"].values():
        spec = {"joint": entry} if isinstance(entry, str) else entry
        if "unit" in spec or "source_range" in spec:
            continue
        for name in spec["joint"] if isinstance(spec["joint"], list) else [spec["joint"]]:
            joint = model.joint(name)
            if joint is not None and joint.moving and joint.angular == angular:
                return
    kind, other = ("revolute or continuous", "prismatic") if angular else ("prismatic", "revolute and continuous")
    ctx.problems.add(
        f"joints.unit {given} applies to {kind} joints only, and no map entry without its own unit drives one; "
        f"the {other} joints use {urdf_unit(not angular)}. Write unit: {'m, cm or mm' if angular else 'rad or deg'} "
        f"(or {{angle: ..., length: ...}}), or omit it for the URDF's units",
        where,
    )


def _order_mimics(model: UrdfModel) -> tuple[MimicJoint, ...]:
    """Mimic joints in dependency order (a mimic may follow another mimic), linear in the joints (model.mimic_order)."""
    return tuple(MimicJoint(j.name, j.mimic.joint, j.mimic.multiplier, j.mimic.offset) for j in model.mimic_order() if j.mimic is not None)

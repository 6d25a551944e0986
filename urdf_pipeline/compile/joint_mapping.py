"""Decide, before reading any value, which source value drives which URDF joint and how (`JointChannel` says the
order of the corrections). Every moving URDF joint is covered exactly once (map, hold or <mimic>); every source name
is mapped or ignored, unless only the data knows the names (`validate --no-data`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from ..errors import Hints, Where, did_you_mean, listing, quoted
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


@dataclass(frozen=True)
class _Section:
    """One robot's `joints` section while it compiles. map and hold share what they have claimed, so a joint driven
    twice, or held and driven, is reported at the second claim, and a joint a refused entry named is not also reported
    as not driven; map, hold and ignore share one bounded "did you mean"."""

    ctx: CompileContext
    here: tuple[str, ...]
    spec: dict[str, Any]
    robot: _RobotJoints
    names: tuple[str, ...] | None
    positions: dict[str, int] | None  # each source name's index; None when names is (only the data knows them)
    hint: Hints = field(default_factory=Hints)
    covered: dict[str, str] = field(default_factory=dict)  # joint -> how ("map entry 'j1'", "hold")
    attempted: set[str] = field(default_factory=set)  # joints named by a rejected entry: already reported, not "not driven" too

    def where(self, *path: str | int) -> Where:
        return self.ctx.where(*self.here, *path)


def compile_joints(
    ctx: CompileContext, robot_key: str, joints_spec: dict[str, Any], names: tuple[str, ...] | None, model: UrdfModel
) -> JointMapping:
    """The robot's joint mapping, every problem of its `joints` section reported in the order of the section's parts:
    map, hold, ignore, unit, the source names left over, slack, then the URDF joints left undriven."""
    here = ("robots", robot_key, "joints")
    limit_spec = joints_spec.get("limits", {})
    robot = _RobotJoints(model, robot_units(joints_spec.get("unit")))
    positions = {name: i for i, name in enumerate(names)} if names is not None else None  # linear in a wide source
    section = _Section(ctx, here, joints_spec, robot, names, positions)
    channels = [c for name, written in joints_spec["map"].items() for c in _entry_channels(section, name, written)]  # in map order
    holds = _holds(section)
    ignored = _ignored(section)
    if robot.units.given is not None:
        _check_unit_applies(ctx, robot, joints_spec, section.where("unit"))
    _check_names_used(section, ignored)
    channels = _with_slack(ctx, (*here, "limits", "slack"), model, limit_spec, channels)
    mimics = tuple(
        MimicJoint(j.name, j.mimic.joint, j.mimic.multiplier, j.mimic.offset) for j in model.mimic_order() if j.mimic is not None
    )
    _check_joints_driven(section)
    on_violation: OnViolation = limit_spec.get("on_violation", "error")
    return JointMapping(tuple(channels), tuple(holds), mimics, on_violation)


def _entry_channels(section: _Section, source_name: str, written: str | dict[str, Any]) -> list[JointChannel]:
    """One map entry's channels: none when its source name or its corrections are wrong (its joints count as attempted,
    so they are not reported as undriven as well), else one per named joint not already driven."""
    where = section.where("map", source_name)
    spec = {"joint": written} if isinstance(written, str) else written
    joint_names = spec["joint"] if isinstance(spec["joint"], list) else [spec["joint"]]
    section.attempted.update(joint_names)
    names, positions = section.names, section.positions
    if names is not None and positions is not None and source_name not in positions:
        section.ctx.problems.add(
            f"'{source_name}' is not a name of source '{section.spec['source']}'{section.hint(source_name, names)}; its names are: {listing(names)}",
            where,
        )
        return []
    entry = _MapEntry(source_name, positions[source_name] if positions is not None else UNKNOWN_INDEX, spec, where)
    if not _corrections_consistent(section.ctx, entry):
        return []
    channels: list[JointChannel] = []
    for joint_name in joint_names:
        if joint_name in section.covered:  # accepted for an earlier entry, so it exists and moves: the one thing wrong is this
            section.ctx.problems.add(
                f"joint '{joint_name}' is driven twice: by {section.covered[joint_name]} and by map entry '{source_name}'", where
            )
            continue
        channel = _channel(section.ctx, section.robot, entry, joint_name)
        if channel is not None:
            section.covered[joint_name] = f"map entry '{source_name}'"
            channels.append(channel)
    return channels


def _holds(section: _Section) -> list[HeldJoint]:
    """The `hold` entries that can be held: a moving, non-mimic URDF joint that no map entry drives, held within its
    limits; each other entry is reported with the one thing wrong with it."""
    model, problems = section.robot.model, section.ctx.problems
    all_joints = [j.name for j in model.joints]
    holds: list[HeldJoint] = []
    for joint_name, value in section.spec.get("hold", {}).items():
        where = section.where("hold", joint_name)
        joint = model.joint(joint_name)
        section.attempted.add(joint_name)
        if joint is None:
            problems.add(f"URDF '{model.name}' has no joint '{joint_name}'{section.hint(joint_name, all_joints)}", where)
        elif not joint.moving:
            problems.add(f"joint '{joint_name}' is {joint.type}; only moving joints can be held", where)
        elif joint.mimic is not None:
            problems.add(f"joint '{joint_name}' is a <mimic> of '{joint.mimic.joint}' and is computed from it; remove it from hold", where)
        elif joint_name in section.covered:
            problems.add(f"joint '{joint_name}' is both held and driven by {section.covered[joint_name]}; keep one", where)
        elif joint.has_limits and not (joint.lower <= value <= joint.upper):
            problems.add(
                f"hold value {value} for '{joint_name}' is outside its URDF limits [{joint.lower}, {joint.upper}] {urdf_unit(joint.angular)}",
                where,
            )
        else:
            section.covered[joint_name] = "hold"
            holds.append(HeldJoint(joint_name, float(value)))
    return holds


def _ignored(section: _Section) -> list[str]:
    """The `ignore` list as source names (7 and "7": a value named by its index), each checked: a name of the source,
    and not mapped as well."""
    names, positions, source = section.names, section.positions, section.spec["source"]
    ignored = [str(name) for name in section.spec.get("ignore", [])]
    for index, name in enumerate(ignored):
        where = section.where("ignore", index)
        if names is not None and positions is not None and name not in positions:
            section.ctx.problems.add(f"ignored name '{name}' is not a name of source '{source}'{section.hint(name, names)}", where)
        elif name in section.spec["map"]:
            section.ctx.problems.add(f"'{name}' is both mapped and ignored; keep one", where)
    return ignored


def _check_names_used(section: _Section, ignored: list[str]) -> None:
    """Every source name is mapped or ignored: a name left over is usually a joint forgotten, so it is said, once."""
    ignored_set = set(ignored)
    unused = [n for n in section.names or () if n not in section.spec["map"] and n not in ignored_set]
    if unused:
        section.ctx.problems.add(
            f"source names neither mapped nor ignored: {listing(unused)}; map each to a URDF joint or list it under ignore",
            section.where("map"),
        )


def _check_joints_driven(section: _Section) -> None:
    """Every moving URDF joint is mapped, held or a <mimic>; joints a refused entry named were reported already."""
    model, covered, attempted = section.robot.model, section.covered, section.attempted
    mimic_joints = {j.name for j in model.joints if j.mimic is not None}
    uncovered = [
        j.name for j in model.joints if j.moving and j.name not in covered and j.name not in mimic_joints and j.name not in attempted
    ]
    if uncovered:
        section.ctx.problems.add(
            f"URDF joints not driven by any source value: {', '.join(uncovered)}; add each to map, or to hold with a fixed value",
            section.where("map"),
        )


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
        problems.add(f"URDF '{model.name}' has no joint '{joint_name}'{did_you_mean(joint_name, [j.name for j in model.joints])}", where)
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

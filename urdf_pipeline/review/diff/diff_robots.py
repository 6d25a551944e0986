"""`diff` of two plans' robots: URDF file, origin and content, meshes, prefixes, joint source, and per source value
its mapping (unit, sign, scale, offset, wrap, ranges, limits in source units), ignores and holds."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ...errors import listing
from ...plan import JointChannel, Plan, RobotPlan
from ...urdf import Joint, UrdfModel, UrdfParseError, parse_urdf_text, quaternion_from_rpy
from .diff_base import Changes, PathValue, Wording, path_value, pose_change, same, value_text

_Mapped = tuple[tuple[str, ...], RobotPlan, dict[str, Any]]  # a source's names, the robot, its report entry
ROBOT_WORDING: Wording = {
    "source": "joints source",
    # said by comparisons of their own below (the URDF's content, the mapping), or following from others (root_frame)
    **dict.fromkeys(("key", "robot_name", "urdf", "root_frame", "nan_policy", "on_violation", "joint_counts", "joints")),
    "appearance": lambda a: a and "[" + ", ".join(f"{c:g}" for c in (*a["color"], a["opacity"])) + "]",  # r, g, b, opacity
    "compare": lambda compare: compare and f"{compare['robot']} {compare['threshold']}",
    "ignored_source_values": None,
}
ROW_WORDING: Wording = dict.fromkeys(  # a mapped value's row: said by _channel_changes, or its URDF's, or its data's
    ("kind", "source_name", "source_index", "joint", "type", "unit", "sign", "offset", "scale", "wrap", "source_range", "target_range")
    + ("limits_source_units", "slack_source_units", "slack", "limits_urdf", "mimic", "hold", "observed")
)


def robot_changes(report: Changes, old: Plan, new: Plan, old_data: dict[str, Any], new_data: dict[str, Any]) -> None:
    """Robots by key: removed, added (with a summary), or compared."""
    old_robots, new_robots = {r.key: r for r in old.robots}, {r.key: r for r in new.robots}
    old_entries, new_entries = ({r["key"]: r for r in data["robots"]} for data in (old_data, new_data))
    for key in sorted(old_robots.keys() | new_robots.keys()):
        subject = f"robot {key}"
        if key not in new_robots:
            report.add("robot", subject, "removed")
        elif key not in old_robots:
            robot = new_robots[key]
            what = (
                f"{len(robot.channels)} mapped value(s) from source '{robot.source}'" if robot.source else "a scene without moving joints"
            )
            report.add(
                "robot", subject, f"added (URDF {report.new_path(robot.urdf_path)}, frame_prefix {value_text(robot.frame_prefix)}, {what})"
            )
        else:
            entries = (old_entries[key], new_entries[key])
            _robot_changes(report, subject, (old, old_robots[key]), (new, new_robots[key]), entries)


def _robot_changes(
    report: Changes,
    subject: str,
    olds: tuple[Plan, RobotPlan],
    news: tuple[Plan, RobotPlan],
    entries: tuple[dict[str, Any], dict[str, Any]],
) -> None:
    """A robot in both plans: its URDF, prefixes and joints source; its mapping and holds only when both have a
    source (a scene has none, and a robot that became one or stopped being one says so in `joints source`)."""
    group, (old_plan, old), (new_plan, new) = "robot", olds, news
    _urdf_and_mesh_changes(report, subject, old, new)
    report.walk(group, subject, entries[0], entries[1], ROBOT_WORDING)
    if old.source is None or new.source is None:
        return
    report.field(group, subject, "NaN policy", old.nan_policy, new.nan_policy)
    report.field(group, subject, "limits slack", _slack(old), _slack(new))
    report.field(group, subject, "limits on_violation", old.on_violation, new.on_violation)
    old_names = old_plan.review_segment.source(old.source).names  # the first segment's, as plan shows them
    new_names = new_plan.review_segment.source(new.source).names
    _mapping_changes(report, subject, (old_names, old, entries[0]), (new_names, new, entries[1]))
    _hold_changes(report, subject, old, new)


def _urdf_and_mesh_changes(report: Changes, subject: str, old: RobotPlan, new: RobotPlan) -> None:
    """The URDF's file, origin and content; what changed inside it (joints, links) only when its hash did, and its
    meshes always (a mesh file can change under an unchanged URDF)."""
    group = "robot"
    report.field(group, subject, "URDF file", report.old_path(old.urdf_path), report.new_path(new.urdf_path))
    if not (old.urdf_origin.startswith("file ") and new.urdf_origin.startswith("file ")):  # a file's origin is its path
        report.field(group, subject, "URDF origin", old.urdf_origin, new.urdf_origin)
    old_model, new_model = _model(old), _model(new)
    if old.urdf_sha256 != new.urdf_sha256:
        report.add(group, subject, f"URDF sha256 {old.urdf_sha256[:12]} -> {new.urdf_sha256[:12]}", old.urdf_sha256, new.urdf_sha256)
        if old_model is not None and new_model is not None:
            _urdf_changes(report, subject, old_model, new_model)
    if old_model is not None and new_model is not None:
        _mesh_changes(report, subject, old_model, new_model)


def _mapping_changes(report: Changes, subject: str, olds: _Mapped, news: _Mapped) -> None:
    """Per source value, in the new source's order (then the old one's): mapped, unmapped, or how its mapping changed;
    then the values that became or stopped being ignored (a source name its plan does not map is ignored)."""
    group, (old_names, old, old_entry), (new_names, new, new_entry) = "robot", olds, news
    rows = [{(row["source_name"], row["joint"]): row for row in entry["joints"]} for entry in (old_entry, new_entry)]
    old_map, new_map = _channels_by_name(old), _channels_by_name(new)
    old_ignored = [n for n in old_names if n not in old_map]
    new_ignored = [n for n in new_names if n not in new_map]
    order = {name: i for i, name in enumerate(new_names)} | {n: len(new_names) + i for i, n in enumerate(old_names) if n not in new_names}
    for name in sorted(old_map.keys() | new_map.keys(), key=lambda n: (order.get(n, len(order)), n)):
        if name not in new_map:
            note = " (now ignored)" if name in new_ignored else ""
            report.add(group, subject, f"{name} -> {_joints(old_map[name])}: removed{note}", _joints(old_map[name]), None)
        elif name not in old_map:
            note = " (was ignored)" if name in old_ignored else ""
            report.add(
                group,
                subject,
                f"{name} -> {_joints(new_map[name])}: added ({_channel_summary(new_map[name][0])}){note}",
                None,
                _joints(new_map[name]),
            )
        else:
            _channel_changes(report, subject, name, old_map[name], new_map[name], rows)
    added = [n for n in new_ignored if n not in old_ignored and n not in old_map]
    removed = [n for n in old_ignored if n not in new_ignored and n not in new_map]
    if added:
        report.add(group, subject, f"ignore added: {', '.join(added)}", None, added)
    if removed:
        report.add(group, subject, f"ignore removed: {', '.join(removed)}", removed, None)


def _hold_changes(report: Changes, subject: str, old: RobotPlan, new: RobotPlan) -> None:
    """Held joints by name: removed, added, or their value changed."""
    group = "robot"
    old_holds, new_holds = {h.joint: h.value for h in old.holds}, {h.joint: h.value for h in new.holds}
    for joint in sorted(old_holds.keys() | new_holds.keys()):
        if joint not in new_holds:
            report.add(group, subject, f"hold {joint} = {value_text(old_holds[joint])}: removed", old_holds[joint], None)
        elif joint not in old_holds:
            report.add(group, subject, f"hold {joint} = {value_text(new_holds[joint])}: added", None, new_holds[joint])
        else:
            report.field(group, subject, f"hold {joint}", old_holds[joint], new_holds[joint])


def _slack(robot: RobotPlan) -> str | None:
    """The robot's limits.slack in the config's own form ("2 deg", "{angle: 2 deg, length: 2 mm}", "0"): each channel holds
    the slack of its joint's kind with the unit it was written in, so a changed joints.unit shows no slack change."""
    return robot.slack_text if robot.channels else None


def _channels_by_name(robot: RobotPlan) -> dict[str, list[JointChannel]]:
    by_name: dict[str, list[JointChannel]] = {}
    for channel in robot.channels:
        by_name.setdefault(channel.source_name, []).append(channel)
    return by_name


def _joints(channels: Sequence[JointChannel]) -> str:
    return ", ".join(c.joint for c in channels)


def _channel_summary(c: JointChannel) -> str:
    if c.source_range is not None:
        return f"source_range {value_text(c.source_range)} onto {value_text(c.target_range)}"
    parts = [f"unit {c.source_unit}", f"sign {value_text(c.sign)}"]
    parts += [f"scale {value_text(c.scale)}"] if c.scale != 1 else []
    parts += [f"offset {value_text(c.offset)}"] if c.offset else []
    parts += [f"wrap {value_text(c.wrap)}"] if c.wrap else []
    return ", ".join(parts)


def _channel_changes(
    report: Changes, subject: str, name: str, old: list[JointChannel], new: list[JointChannel], rows: list[dict[tuple[str, str], Any]]
) -> None:
    old_joints, new_joints = [c.joint for c in old], [c.joint for c in new]
    if sorted(old_joints) != sorted(new_joints):
        report.add("robot", subject, f"{name}: remapped {_joints(old)} -> {_joints(new)}", _joints(old), _joints(new))
    pairs: list[tuple[JointChannel, JointChannel]]
    if sorted(old_joints) == sorted(new_joints):
        pairs = [(o, next(n for n in new if n.joint == o.joint)) for o in old]
    elif len(old) == len(new):
        pairs = list(zip(old, new, strict=True))
    else:
        pairs = [(o, n) for o in old for n in new if o.joint == n.joint]
    for o, n in pairs:
        label = f"{name} -> {n.joint}"
        for field in ("sign", "unit", "scale", "offset", "wrap", "source_range"):
            attribute = "source_unit" if field == "unit" else field
            report.field("robot", subject, f"{label}: {field}", getattr(o, attribute), getattr(n, attribute))
        if not (_follows_limits(o) and _follows_limits(n)):  # URDF limits changes are reported with the URDF
            report.field("robot", subject, f"{label}: joint_range", o.target_range, n.target_range)
        if o.joint == n.joint:  # what the changes above (or the URDF's) mean for the data, as plan and check print it
            report.field("robot", subject, f"{label}: limits (source units)", _limits(o), _limits(n))
        old_row, new_row = rows[0][(name, o.joint)], rows[1][(name, n.joint)]
        report.walk("robot", subject, old_row, new_row, ROW_WORDING, f"{label}: ")


def _limits(c: JointChannel) -> tuple[float, ...] | None:
    """JointChannel.limits_in_source_unit to 6 significant digits, as plan's text, check and the run print it."""
    limits = c.limits_in_source_unit
    return tuple(float(f"{v:.6g}") for v in limits) if limits is not None else None


def _follows_limits(c: JointChannel) -> bool:
    return c.target_range is None or same(c.target_range, (c.lower, c.upper))


def _model(robot: RobotPlan) -> UrdfModel | None:
    try:
        return parse_urdf_text(robot.urdf_text, str(robot.urdf_path))
    except UrdfParseError:
        return None


def _urdf_changes(report: Changes, subject: str, old: UrdfModel, new: UrdfModel) -> None:
    group = "robot"
    report.field(group, subject, "URDF robot name", old.name, new.name)
    report.field(group, subject, "URDF root link", old.root_link, new.root_link)
    _added_removed(report, subject, "URDF joints", [j.name for j in old.joints], [j.name for j in new.joints])
    _added_removed(report, subject, "URDF links", list(old.links), list(new.links))
    new_joints = {j.name: j for j in new.joints}
    for joint in old.joints:
        if joint.name in new_joints:
            _urdf_joint_changes(report, subject, joint, new_joints[joint.name])


def _added_removed(report: Changes, subject: str, what: str, old: list[str], new: list[str]) -> None:
    added = [n for n in new if n not in old]
    removed = [n for n in old if n not in new]
    if added:
        report.add("robot", subject, f"{what} added: {listing(added)}", None, added)
    if removed:
        report.add("robot", subject, f"{what} removed: {listing(removed)}", removed, None)


def _urdf_joint_changes(report: Changes, subject: str, old: Joint, new: Joint) -> None:
    label = f"URDF joint {old.name}"
    for attribute in ("type", "parent", "child"):
        report.field("robot", subject, f"{label}: {attribute}", getattr(old, attribute), getattr(new, attribute))
    moved = pose_change(old.xyz, quaternion_from_rpy(*old.rpy), new.xyz, quaternion_from_rpy(*new.rpy))
    if moved is not None:
        report.add("robot", subject, f"{label}: origin {moved}", [*old.xyz, *old.rpy], [*new.xyz, *new.rpy])
    report.field("robot", subject, f"{label}: axis", old.axis, new.axis)
    if old.type != "continuous" or new.type != "continuous":
        report.field("robot", subject, f"{label}: limits", (old.lower, old.upper), (new.lower, new.upper))
    old_mimic = (old.mimic.joint, old.mimic.multiplier, old.mimic.offset) if old.mimic else None
    new_mimic = (new.mimic.joint, new.mimic.multiplier, new.mimic.offset) if new.mimic else None
    report.field("robot", subject, f"{label}: mimic (joint, multiplier, offset)", old_mimic, new_mimic)


def _mesh_changes(report: Changes, subject: str, old: UrdfModel, new: UrdfModel) -> None:
    """Meshes of the same link resolved to another file (package_paths changed, say)."""

    def by_link(model: UrdfModel, base: Path) -> dict[tuple[str, str], list[PathValue]]:
        meshes: dict[tuple[str, str], list[PathValue]] = {}
        for mesh in model.meshes:
            meshes.setdefault((mesh.link, mesh.kind), []).append(path_value(Path(mesh.uri), base))
        return meshes

    old_meshes, new_meshes = by_link(old, report.old_base), by_link(new, report.new_base)
    for key in sorted(old_meshes.keys() & new_meshes.keys()):
        report.field("robot", subject, f"mesh of link {key[0]} ({key[1]})", old_meshes[key], new_meshes[key])

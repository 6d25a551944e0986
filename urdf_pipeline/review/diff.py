"""The semantic difference of two compiled plans, for `urdf-pipeline diff` and pull-request review.

Two configs are compiled with `compile_config` and their plans compared, not their YAML: key order, comments,
quoting, flow vs block style and equal spellings (`rpy_deg` vs the same `quaternion_xyzw`) make no difference.
Floats are compared with a tolerance of 1e-9, `where` fields (line numbers) and labels are ignored, and paths are
compared relative to each config's folder (a path equal either relatively or absolutely is the same path), so a
config moved together with its inputs shows no change.

The report is one line per change, grouped: robots (by key), then edges (the root frame, static edges by
(parent, child), temporal edges), then sources (by name), then the output; within a group in a fixed order, so
the same two plans always give the same text.

`diff CONFIG --git REV` compiles the config's text at REV (`git show REV:./NAME`, run in the config's folder)
from a hidden temporary file beside the config, so relative paths resolve as for the working tree's config.
Everything else the old config refers to (URDF, data, sidecar edge files) is read from the working tree.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

from ..errors import listing
from ..plan import (
    EdgePlan,
    IndexPlan,
    JointChannel,
    LeRobotSourcePlan,
    Plan,
    RobotPlan,
    SourcePlan,
    TemporalEdgePlan,
)
from ..urdf.geometry import quaternion_from_rpy
from ..urdf.model import Joint, UrdfModel, UrdfParseError, parse_urdf_text
from .diff_base import Change, PathValue, _moved, _path_value, _Report, _rounded, _same, _text

# ---------------------------------------------------------------------------------------------------------- values


# ---------------------------------------------------------------------------------------------------------- the diff


def diff_plans(old: Plan, new: Plan) -> list[Change]:
    """Every semantic difference from old to new, in report order (empty when the plans are equivalent)."""
    report = _Report(old.config_path.parent, new.config_path.parent)
    old_robots, new_robots = {r.key: r for r in old.robots}, {r.key: r for r in new.robots}
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
                "robot", subject, f"added (URDF {report.new_path(robot.urdf_path)}, frame_prefix {_text(robot.frame_prefix)}, {what})"
            )
        else:
            _robot_changes(report, subject, old, old_robots[key], new, new_robots[key])
    _edge_changes(report, old, new)
    _source_changes(report, old, new)
    _output_changes(report, old, new)
    return report.changes


# ---------------------------------------------------------------------------------------------------------- robots


def _robot_changes(report: _Report, subject: str, old_plan: Plan, old: RobotPlan, new_plan: Plan, new: RobotPlan) -> None:
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
    report.field(group, subject, "entity_path_prefix", old.entity_path_prefix, new.entity_path_prefix)
    report.field(group, subject, "frame_prefix", old.frame_prefix, new.frame_prefix)
    report.field(group, subject, "collision_geometries", _collisions(old), _collisions(new))
    report.field(group, subject, "joints source", old.source, new.source)
    if old.source is None or new.source is None:
        return
    report.field(group, subject, "NaN policy", old.nan_policy, new.nan_policy)
    report.field(group, subject, "limits slack (source units)", _slack(old), _slack(new))
    report.field(group, subject, "limits on_violation", old.on_violation, new.on_violation)

    old_names, new_names = old_plan.source(old.source).names, new_plan.source(new.source).names
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
            _channel_changes(report, subject, name, old_map[name], new_map[name])
    added = [n for n in new_ignored if n not in old_ignored and n not in old_map]
    removed = [n for n in old_ignored if n not in new_ignored and n not in new_map]
    if added:
        report.add(group, subject, f"ignore added: {', '.join(added)}", None, added)
    if removed:
        report.add(group, subject, f"ignore removed: {', '.join(removed)}", removed, None)

    old_holds, new_holds = {h.joint: h.value for h in old.holds}, {h.joint: h.value for h in new.holds}
    for joint in sorted(old_holds.keys() | new_holds.keys()):
        if joint not in new_holds:
            report.add(group, subject, f"hold {joint} = {_text(old_holds[joint])}: removed", old_holds[joint], None)
        elif joint not in old_holds:
            report.add(group, subject, f"hold {joint} = {_text(new_holds[joint])}: added", None, new_holds[joint])
        else:
            report.field(group, subject, f"hold {joint}", old_holds[joint], new_holds[joint])


def _collisions(robot: RobotPlan) -> str:
    return "keep" if robot.keep_collisions else "drop"


def _slack(robot: RobotPlan) -> float | None:
    """The config's limits.slack (source units): each channel holds it in URDF units, times its gain."""
    return next((c.slack_in_source_unit for c in robot.channels if c.slack_in_source_unit is not None), None)


def _channels_by_name(robot: RobotPlan) -> dict[str, list[JointChannel]]:
    by_name: dict[str, list[JointChannel]] = {}
    for channel in robot.channels:
        by_name.setdefault(channel.source_name, []).append(channel)
    return by_name


def _joints(channels: Sequence[JointChannel]) -> str:
    return ", ".join(c.joint for c in channels)


def _channel_summary(c: JointChannel) -> str:
    if c.source_range is not None:
        return f"source_range {_text(c.source_range)} onto {_text(c.target_range)}"
    parts = [f"unit {c.source_unit}", f"sign {_text(c.sign)}"]
    parts += [f"scale {_text(c.scale)}"] if c.scale != 1 else []
    parts += [f"offset {_text(c.offset)}"] if c.offset else []
    parts += [f"wrap {_text(c.wrap)}"] if c.wrap else []
    return ", ".join(parts)


def _channel_changes(report: _Report, subject: str, name: str, old: list[JointChannel], new: list[JointChannel]) -> None:
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
        report.field("robot", subject, f"{label}: sign", o.sign, n.sign)
        report.field("robot", subject, f"{label}: unit", o.source_unit, n.source_unit)
        report.field("robot", subject, f"{label}: scale", o.scale, n.scale)
        report.field("robot", subject, f"{label}: offset", o.offset, n.offset)
        report.field("robot", subject, f"{label}: wrap", o.wrap, n.wrap)
        report.field("robot", subject, f"{label}: source_range", o.source_range, n.source_range)
        if not (_follows_limits(o) and _follows_limits(n)):  # URDF limits changes are reported with the URDF
            report.field("robot", subject, f"{label}: joint_range", o.target_range, n.target_range)
        if o.joint == n.joint:  # what the changes above (or the URDF's) mean for the data, as plan and check print it
            report.field("robot", subject, f"{label}: limits (source units)", _limits(o), _limits(n))


def _limits(c: JointChannel) -> tuple[float, ...] | None:
    """JointChannel.limits_in_source_unit to 6 significant digits, as plan's text, check and the run print it."""
    limits = c.limits_in_source_unit
    return tuple(float(f"{v:.6g}") for v in limits) if limits is not None else None


def _follows_limits(c: JointChannel) -> bool:
    return c.target_range is None or _same(c.target_range, (c.lower, c.upper))


def _model(robot: RobotPlan) -> UrdfModel | None:
    try:
        return parse_urdf_text(robot.urdf_text, str(robot.urdf_path))
    except UrdfParseError:
        return None


def _urdf_changes(report: _Report, subject: str, old: UrdfModel, new: UrdfModel) -> None:
    group = "robot"
    report.field(group, subject, "URDF robot name", old.name, new.name)
    report.field(group, subject, "URDF root link", old.root_link, new.root_link)
    _added_removed(report, subject, "URDF joints", [j.name for j in old.joints], [j.name for j in new.joints])
    _added_removed(report, subject, "URDF links", list(old.links), list(new.links))
    new_joints = {j.name: j for j in new.joints}
    for joint in old.joints:
        if joint.name in new_joints:
            _urdf_joint_changes(report, subject, joint, new_joints[joint.name])


def _added_removed(report: _Report, subject: str, what: str, old: list[str], new: list[str]) -> None:
    added = [n for n in new if n not in old]
    removed = [n for n in old if n not in new]
    if added:
        report.add("robot", subject, f"{what} added: {listing(added)}", None, added)
    if removed:
        report.add("robot", subject, f"{what} removed: {listing(removed)}", removed, None)


def _urdf_joint_changes(report: _Report, subject: str, old: Joint, new: Joint) -> None:
    label = f"URDF joint {old.name}"
    report.field("robot", subject, f"{label}: type", old.type, new.type)
    report.field("robot", subject, f"{label}: parent", old.parent, new.parent)
    report.field("robot", subject, f"{label}: child", old.child, new.child)
    moved = _moved(old.xyz, quaternion_from_rpy(*old.rpy), new.xyz, quaternion_from_rpy(*new.rpy))
    if moved is not None:
        report.add("robot", subject, f"{label}: origin {moved}", [*old.xyz, *old.rpy], [*new.xyz, *new.rpy])
    report.field("robot", subject, f"{label}: axis", old.axis, new.axis)
    if old.type != "continuous" or new.type != "continuous":
        report.field("robot", subject, f"{label}: limits", (old.lower, old.upper), (new.lower, new.upper))
    old_mimic = (old.mimic.joint, old.mimic.multiplier, old.mimic.offset) if old.mimic else None
    new_mimic = (new.mimic.joint, new.mimic.multiplier, new.mimic.offset) if new.mimic else None
    report.field("robot", subject, f"{label}: mimic (joint, multiplier, offset)", old_mimic, new_mimic)


def _mesh_changes(report: _Report, subject: str, old: UrdfModel, new: UrdfModel) -> None:
    """Meshes of the same link resolved to another file (package_paths changed, say)."""

    def by_link(model: UrdfModel, base: Path) -> dict[tuple[str, str], list[PathValue]]:
        meshes: dict[tuple[str, str], list[PathValue]] = {}
        for mesh in model.meshes:
            meshes.setdefault((mesh.link, mesh.kind), []).append(_path_value(Path(mesh.uri), base))
        return meshes

    old_meshes, new_meshes = by_link(old, report.old_base), by_link(new, report.new_base)
    for key in sorted(old_meshes.keys() & new_meshes.keys()):
        report.field("robot", subject, f"mesh of link {key[0]} ({key[1]})", old_meshes[key], new_meshes[key])


# ---------------------------------------------------------------------------------------------------------- edges


def _edge_changes(report: _Report, old: Plan, new: Plan) -> None:
    report.field("edges", "frames", "root", old.root_frame, new.root_frame)
    old_edges = {(e.parent, e.child): e for e in old.edges}
    new_edges = {(e.parent, e.child): e for e in new.edges}
    for key in sorted(old_edges.keys() | new_edges.keys()):
        subject = f"edge {key[0]} -> {key[1]}"
        if key not in new_edges:
            report.add("edges", subject, f"removed (was {_edge_summary(old_edges[key])})")
        elif key not in old_edges:
            report.add("edges", subject, f"added ({_edge_summary(new_edges[key])})")
        else:
            _static_edge_changes(report, subject, old_edges[key], new_edges[key])
    old_temporal = {(e.parent, e.child): e for e in old.temporal_edges}
    new_temporal = {(e.parent, e.child): e for e in new.temporal_edges}
    for key in sorted(old_temporal.keys() | new_temporal.keys()):
        subject = f"temporal edge {key[0]} -> {key[1]}"
        if key not in new_temporal:
            report.add("edges", subject, "removed")
        elif key not in old_temporal:
            report.add("edges", subject, f"added ({_temporal_summary(new_temporal[key])})")
        else:
            o, n = old_temporal[key], new_temporal[key]
            report.field("edges", subject, "source", o.source, n.source)
            report.field("edges", subject, "translation", o.translation_names, n.translation_names)
            report.field("edges", subject, "quaternion_xyzw", o.quaternion_names, n.quaternion_names)


def _edge_summary(edge: EdgePlan) -> str:
    if edge.kind == "fixed_chain" and edge.fixed_chain is not None:
        return f"fixed_chain {edge.fixed_chain.start} -> {edge.fixed_chain.end} of robot {edge.fixed_chain.robot}"
    if edge.kind == "assume_identity":
        return "assume_identity"
    return f"static, translation {_text(_rounded(edge.translation))}, quaternion_xyzw {_text(_rounded(edge.quaternion_xyzw))}"


def _temporal_summary(edge: TemporalEdgePlan) -> str:
    return f"source {edge.source}, translation {_text(edge.translation_names)}, quaternion_xyzw {_text(edge.quaternion_names)}"


def _static_edge_changes(report: _Report, subject: str, old: EdgePlan, new: EdgePlan) -> None:
    report.field("edges", subject, "kind", old.kind, new.kind)
    if old.fixed_chain is not None and new.fixed_chain is not None:
        report.field("edges", subject, "fixed_chain robot", old.fixed_chain.robot, new.fixed_chain.robot)
        report.field("edges", subject, "fixed_chain from", old.fixed_chain.start, new.fixed_chain.start)
        report.field("edges", subject, "fixed_chain to", old.fixed_chain.end, new.fixed_chain.end)
        report.field("edges", subject, "fixed_chain joints", old.fixed_chain.joints, new.fixed_chain.joints)
    moved = _moved(old.translation, old.quaternion_xyzw, new.translation, new.quaternion_xyzw)
    if moved is not None:
        report.add("edges", subject, moved, [*old.translation, *old.quaternion_xyzw], [*new.translation, *new.quaternion_xyzw])


# ---------------------------------------------------------------------------------------------------------- sources

_KIND_PATHS = {"parquet": "path", "lerobot": "root", "mcap": "path", "hdf5": "path", "rrd": "path"}
_NOT_COMPARED = {"name", "where", "names", "path", "root", "rows", "per_segment", "episode"}  # rows: the data's, not the config's


def _kind(source: SourcePlan) -> str:
    return type(source).__name__.removesuffix("SourcePlan").lower()


def _source_changes(report: _Report, old: Plan, new: Plan) -> None:
    old_sources, new_sources = {s.name: s for s in old.sources}, {s.name: s for s in new.sources}
    for name in sorted(old_sources.keys() | new_sources.keys()):
        subject = f"source {name}"
        if name not in new_sources:
            report.add("sources", subject, "removed")
            continue
        if name not in old_sources:
            source = new_sources[name]
            report.add("sources", subject, f"added ({_kind(source)} {_source_files(report.new_path, new, name)[0]})")
            continue
        o, n = old_sources[name], new_sources[name]
        report.field("sources", subject, "kind", _kind(o), _kind(n))
        old_files, new_files = _source_files(report.old_path, old, name), _source_files(report.new_path, new, name)
        if len(old_files) == 1 and len(new_files) == 1:
            report.field("sources", subject, _KIND_PATHS[_kind(n)], old_files[0], new_files[0])
        elif not _same(old_files, new_files):
            added = [str(f) for f in new_files if f not in old_files]
            removed = [str(f) for f in old_files if f not in new_files]
            what = "; ".join(
                part for part in (f"added: {listing(added)}" if added else "", f"removed: {listing(removed)}" if removed else "") if part
            )
            report.add(
                "sources",
                subject,
                f"files {len(old_files)} -> {len(new_files)}" + (f" ({what})" if what else ""),
                [str(f) for f in old_files],
                [str(f) for f in new_files],
            )
        new_fields = {f.name for f in fields(n)}
        for f in fields(o):
            if f.name in new_fields and f.name not in _NOT_COMPARED:
                report.field("sources", subject, f.name, _source_value(getattr(o, f.name)), _source_value(getattr(n, f.name)))
        if isinstance(o, LeRobotSourcePlan) and isinstance(n, LeRobotSourcePlan):
            report.field("sources", subject, "episode", _episode(o), _episode(n))
        _names_changes(report, subject, o.names, n.names)


def _source_files(path_value: Callable[[Path], PathValue], plan: Plan, name: str) -> list[PathValue]:
    """The files a source reads over all segments (one, or every file of a glob), in segment order."""
    files: list[PathValue] = []
    segments = plan.dataset.segments
    plans = [s for segment in segments for s in segment.sources if s.name == name] or [plan.source(name)]
    for source in plans:
        value = path_value(source.root if isinstance(source, LeRobotSourcePlan) else source.path)
        if value not in files:
            files.append(value)
    return files


def _episode(source: LeRobotSourcePlan) -> str:
    return "one per segment" if source.per_segment else str(source.episode)


def _source_value(value: Any) -> Any:
    if isinstance(value, IndexPlan):
        return f"{value.column} ({value.kind}" + (f", {value.unit})" if value.unit else ")")
    return value


def _names_changes(report: _Report, subject: str, old: tuple[str, ...], new: tuple[str, ...]) -> None:
    if old == new:
        return
    added = [n for n in new if n not in old]
    removed = [n for n in old if n not in new]
    if not added and not removed:
        report.add("sources", subject, f"names reordered: {_text(old)} -> {_text(new)}", list(old), list(new))
        return
    parts = ([f"added {listing(added)}"] if added else []) + ([f"removed {listing(removed)}"] if removed else [])
    report.add("sources", subject, f"names: {'; '.join(parts)}", list(old), list(new))


# ---------------------------------------------------------------------------------------------------------- output


def _output_changes(report: _Report, old: Plan, new: Plan) -> None:
    subject = "output"
    report.field("output", subject, "application_id", old.output.application_id, new.output.application_id)
    if old.dataset is None or new.dataset is None:
        report.field("output", subject, "path", report.old_path(old.output.path), report.new_path(new.output.path))
        report.field("output", subject, "segment", old.output.recording_id, new.output.recording_id)
        return
    report.field("output", subject, "layout", old.dataset.layout, new.dataset.layout)
    old_model = report.old_path(old.dataset.model) if old.dataset.model else None
    new_model = report.new_path(new.dataset.model) if new.dataset.model else None
    report.field("output", subject, "model", old_model, new_model)
    old_manifest, new_manifest = report.old_path(old.dataset.manifest), report.new_path(new.dataset.manifest)
    if old_manifest != new_manifest and _manifest_key(report.old_path, old) != _manifest_key(report.new_path, new):
        report.add("output", subject, f"manifest {old_manifest} -> {new_manifest}", str(old_manifest), str(new_manifest))
    old_segments, new_segments = old.dataset.segments, new.dataset.segments
    old_ids, new_ids = [s.id for s in old_segments], [s.id for s in new_segments]
    pairs = []
    if len(old_ids) == len(new_ids):  # same count: pair by position (a changed template renames every segment)
        pairs = list(zip(old_segments, new_segments, strict=True))
        renamed = [f"{o.id} -> {n.id}" for o, n in pairs if o.id != n.id]
        if len(pairs) == 1 and renamed:
            report.add("output", subject, f"segment {renamed[0]}", old_ids[0], new_ids[0])
        elif renamed:
            report.add("output", subject, f"segment ids ({len(renamed)} of {len(pairs)}): {listing(renamed, limit=3)}", old_ids, new_ids)
    else:
        added = [i for i in new_ids if i not in old_ids]
        removed = [i for i in old_ids if i not in new_ids]
        parts = ([f"added {listing(added, limit=5)}"] if added else []) + ([f"removed {listing(removed, limit=5)}"] if removed else [])
        report.add("output", subject, f"segments {len(old_ids)} -> {len(new_ids)} ({'; '.join(parts)})", old_ids, new_ids)
        new_by_id = {s.id: s for s in new_segments}
        pairs = [(o, new_by_id[o.id]) for o in old_segments if o.id in new_by_id]
    moved = [(report.old_path(o.output), report.new_path(n.output)) for o, n in pairs]
    moved = [(o, n) for (o, n), (os_, ns) in zip(moved, pairs, strict=True) if o != n and o.relative.replace(os_.id, ns.id) != n.relative]
    if len(pairs) == 1 and moved:
        report.field("output", subject, "path", *moved[0])
    elif moved:
        shown = listing([f"{o} -> {n}" for o, n in moved], limit=2)
        report.add(
            "output",
            subject,
            f"paths ({len(moved)} of {len(pairs)} segments): {shown}",
            [str(o) for o, _ in moved],
            [str(n) for _, n in moved],
        )


def _manifest_key(path_value: Callable[[Path], PathValue], plan: Plan) -> tuple[PathValue, str | None]:
    """The manifest's folder and name; None for the default name (after the config's file), so configs of other names compare."""
    manifest = plan.dataset.manifest
    return path_value(manifest.parent), None if manifest.name == f"{plan.config_path.stem}.manifest.json" else manifest.name


# ---------------------------------------------------------------------------------------------------------- reports


# ---------------------------------------------------------------------------------------------------------- compiling

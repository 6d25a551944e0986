"""The semantic difference of two compiled plans, for `urdf-pipeline diff` and pull-request review.

Two configs are compiled with `compile_config` and their plans compared, not their YAML: key order, comments,
quoting, flow vs block style and equal spellings (`rpy_deg` vs the same `quaternion_xyzw`) make no difference.
Floats are compared with a tolerance of 1e-9, `where` fields (line numbers) and labels are ignored, and paths are
compared relative to each config's folder (a path equal either relatively or absolutely is the same path), so a
config moved together with its inputs shows no change.

The changes come in a fixed order, grouped: robots (by key: diff_robots.py), then edges (the root frame, static edges
by (parent, child), temporal edges), then sources (by name), then the output; within a group in a fixed order, so
the same two plans always give the same report (diff_base.DiffReport; diff_render.py prints it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import Any

from ...errors import listing
from ...plan import EdgePlan, IndexPlan, LeRobotSourcePlan, Plan, SourcePlan, TemporalEdgePlan
from .diff_base import Change, Changes, PathValue, pose_change, rounded_text, same, value_text
from .diff_robots import robot_changes


def diff_plans(old: Plan, new: Plan) -> tuple[Change, ...]:
    """Every semantic difference from old to new, in report order (empty when the plans are equivalent)."""
    report = Changes(old.config_path.parent, new.config_path.parent)
    robot_changes(report, old, new)
    _edge_changes(report, old, new)
    _source_changes(report, old, new)
    _output_changes(report, old, new)
    return tuple(report.changes)


# ---------------------------------------------------------------------------------------------------------- edges


def _edge_changes(report: Changes, old: Plan, new: Plan) -> None:
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
            report.field("edges", subject, "tf topic", o.tf_topic or "none", n.tf_topic or "none")  # a bag's /tf edge
            report.field("edges", subject, "translation", o.translation_names, n.translation_names)
            report.field("edges", subject, "quaternion_xyzw", o.quaternion_names, n.quaternion_names)


def _edge_summary(edge: EdgePlan) -> str:
    if edge.kind == "fixed_chain" and edge.fixed_chain is not None:
        return f"fixed_chain {edge.fixed_chain.start} -> {edge.fixed_chain.end} of robot {edge.fixed_chain.robot}"
    if edge.kind == "assume_identity":
        return "assume_identity"
    return f"static, translation {rounded_text(edge.translation)}, quaternion_xyzw {rounded_text(edge.quaternion_xyzw)}"


def _temporal_summary(edge: TemporalEdgePlan) -> str:
    if edge.tf_topic is not None:
        return f"source {edge.source}, {edge.tf_topic} of its bag"
    return f"source {edge.source}, translation {value_text(edge.translation_names)}, quaternion_xyzw {value_text(edge.quaternion_names)}"


def _static_edge_changes(report: Changes, subject: str, old: EdgePlan, new: EdgePlan) -> None:
    report.field("edges", subject, "kind", old.kind, new.kind)
    if old.fixed_chain is not None and new.fixed_chain is not None:
        report.field("edges", subject, "fixed_chain robot", old.fixed_chain.robot, new.fixed_chain.robot)
        report.field("edges", subject, "fixed_chain from", old.fixed_chain.start, new.fixed_chain.start)
        report.field("edges", subject, "fixed_chain to", old.fixed_chain.end, new.fixed_chain.end)
        report.field("edges", subject, "fixed_chain joints", old.fixed_chain.joints, new.fixed_chain.joints)
    moved = pose_change(old.translation, old.quaternion_xyzw, new.translation, new.quaternion_xyzw)
    if moved is not None:
        report.add("edges", subject, moved, [*old.translation, *old.quaternion_xyzw], [*new.translation, *new.quaternion_xyzw])


# ---------------------------------------------------------------------------------------------------------- sources

_KIND_PATHS = {"parquet": "path", "lerobot": "root", "mcap": "path", "hdf5": "path", "rrd": "path", "csv": "path"}
# rows: the data's, not the config's; remote: the object a path names (its URL is compared as the path)
_NOT_COMPARED = {"name", "where", "names", "path", "root", "rows", "per_segment", "episode", "remote"}


def _kind(source: SourcePlan) -> str:
    return type(source).__name__.removesuffix("SourcePlan").lower()


def _source_changes(report: Changes, old: Plan, new: Plan) -> None:
    old_sources, new_sources = {s.name: s for s in old.review_segment.sources}, {s.name: s for s in new.review_segment.sources}
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
        elif not same(old_files, new_files):
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
    plans = [s for segment in segments for s in segment.sources if s.name == name] or [plan.review_segment.source(name)]
    for source in plans:
        remote = getattr(source, "remote", None)
        if remote is not None:  # a remote file is its URL (a new version of it is no change to the config)
            value = PathValue(remote.url, remote.url)
        else:
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


def _names_changes(report: Changes, subject: str, old: tuple[str, ...], new: tuple[str, ...]) -> None:
    if old == new:
        return
    added = [n for n in new if n not in old]
    removed = [n for n in old if n not in new]
    if not added and not removed:
        report.add("sources", subject, f"names reordered: {value_text(old)} -> {value_text(new)}", list(old), list(new))
        return
    parts = ([f"added {listing(added)}"] if added else []) + ([f"removed {listing(removed)}"] if removed else [])
    report.add("sources", subject, f"names: {'; '.join(parts)}", list(old), list(new))


# ---------------------------------------------------------------------------------------------------------- output


def _output_changes(report: Changes, old: Plan, new: Plan) -> None:
    subject = "output"
    report.field("output", subject, "application_id", old.application_id, new.application_id)
    report.field("output", subject, "layout", old.dataset.layout, new.dataset.layout)
    report.field("output", subject, "joint_series", old.dataset.joint_series, new.dataset.joint_series)
    report.field("output", subject, "trails", _trails(old), _trails(new))
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


def _trails(plan: Plan) -> str:
    """The trails as one comparable text: which link, in which frame, how drawn, over which window."""
    return (
        "; ".join(f"{t.label} ({t.style}, window {t.window if t.window is not None else 'all'} {t.window_unit})" for t in plan.trails)
        or "none"
    )


def _manifest_key(path_value: Callable[[Path], PathValue], plan: Plan) -> tuple[PathValue, str | None]:
    """The manifest's folder and name; None for the default name (after the config's file), so configs of other names compare."""
    manifest = plan.dataset.manifest
    return path_value(manifest.parent), None if manifest.name == f"{plan.config_path.stem}.manifest.json" else manifest.name

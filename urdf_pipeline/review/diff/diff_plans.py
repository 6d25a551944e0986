"""The semantic difference of two compiled plans (what counts as none: docs/commands.md#diff), in a fixed order:
robots (diff_robots.py), edges, sources, output.

What the plan report holds is compared as its plain data (`Changes.walk` over two `report_model.as_data`): a field
added to the report is a change `diff` shows, labelled with its name. The wording tables (`*_WORDING`) name the
fields said otherwise: with another label, or by a comparison of their own (a moved edge, a remapped value, the
URDF's content, every segment's files), which reads the plans where the report holds less (absolute paths, meshes).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from ...errors import listing
from ...plan import EdgePlan, LeRobotSourcePlan, Plan, TemporalEdgePlan
from ..plan_report.report import build_report
from ..plan_report.report_model import as_data
from .diff_base import Change, Changes, PathValue, Wording, added_removed, pose_change, rounded_text, same, value_text
from .diff_robots import robot_changes

_SAID = ("config", "root_frame", "robots", "edges", "sources", "output", "frame_tree", "warnings", "sample", "pictures", "report_version")
PLAN_WORDING: Wording = dict.fromkeys(_SAID)  # each group below, or no change of the config's (warnings, the report's version)
TEMPORAL_WORDING: Wording = {  # the indices follow from the names (a source's names are compared with it)
    "translation_names": "translation",
    "quaternion_xyzw_names": "quaternion_xyzw",
    "tf_topic": lambda topic: topic or "none",  # a bag's /tf edge
    **dict.fromkeys(("entity", "translation_indices", "quaternion_xyzw_indices")),
}
EDGE_WORDING: Wording = {"temporal": TEMPORAL_WORDING, **dict.fromkeys(("parent", "child", "origin", "translation_m", "rotation_rpy_deg"))}
SOURCE_WORDING: Wording = {  # a source's settings: each its own field, but for the files, names and episode (compared apart)
    "index": lambda index: index and f"{index['column']} ({index['kind']}" + (f", {index['unit']})" if index["unit"] else ")"),
    **dict.fromkeys(("name", "kind", "path", "root", "names", "rows", "per_segment", "episode")),  # rows: the data's
}
OUTPUT_WORDING: Wording = {
    "joint_series": bool,
    "trails": lambda trails: (
        "; ".join(f"trail of {t['robot']}'s {t['link']} in {t['frame']} ({t['style']}, window {t['window']})" for t in trails or ())
        or "none"
    ),
    **dict.fromkeys(("segment_count", "segments", "model", "manifest")),  # compared apart: paths relative or absolute
}


def diff_plans(old: Plan, new: Plan) -> tuple[Change, ...]:
    """Every semantic difference from old to new, in report order (empty when the plans are equivalent)."""
    report = Changes(old.config_path.parent, new.config_path.parent)
    old_data, new_data = as_data(build_report(old)), as_data(build_report(new))
    robot_changes(report, old, new, old_data, new_data)
    _edge_changes(report, old, new, old_data, new_data)
    _source_changes(report, old, new, old_data, new_data)
    _output_changes(report, old, new, old_data["output"], new_data["output"])
    report.walk("plan", "plan", old_data, new_data, PLAN_WORDING)
    return tuple(report.changes)


def _by_key(items: list[dict[str, Any]], *names: str) -> dict[Any, dict[str, Any]]:
    """A list of the report's data keyed by one field (a name) or by several ((parent, child))."""
    return {item[names[0]] if len(names) == 1 else tuple(item[name] for name in names): item for item in items}


# ---------------------------------------------------------------------------------------------------------- edges


def _edge_changes(report: Changes, old: Plan, new: Plan, old_data: dict[str, Any], new_data: dict[str, Any]) -> None:
    report.field("edges", "frames", "root", old.root_frame, new.root_frame)
    old_data_edges, new_data_edges = _by_key(old_data["edges"], "parent", "child"), _by_key(new_data["edges"], "parent", "child")
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
            report.walk("edges", subject, old_data_edges[key], new_data_edges[key], EDGE_WORDING)
    old_temporal = {(e.parent, e.child): e for e in old.temporal_edges}
    new_temporal = {(e.parent, e.child): e for e in new.temporal_edges}
    for key in sorted(old_temporal.keys() | new_temporal.keys()):
        subject = f"temporal edge {key[0]} -> {key[1]}"
        if key not in new_temporal:
            report.add("edges", subject, "removed")
        elif key not in old_temporal:
            report.add("edges", subject, f"added ({_temporal_summary(new_temporal[key])})")
        else:
            report.walk("edges", subject, old_data_edges[key], new_data_edges[key], EDGE_WORDING)


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
        for name, attribute in (("robot", "robot"), ("from", "start"), ("to", "end"), ("joints", "joints")):
            report.field("edges", subject, f"fixed_chain {name}", getattr(old.fixed_chain, attribute), getattr(new.fixed_chain, attribute))
    moved = pose_change(old.translation, old.quaternion_xyzw, new.translation, new.quaternion_xyzw)
    if moved is not None:
        report.add("edges", subject, moved, [*old.translation, *old.quaternion_xyzw], [*new.translation, *new.quaternion_xyzw])


# ---------------------------------------------------------------------------------------------------------- sources


def _source_changes(report: Changes, old: Plan, new: Plan, old_data: dict[str, Any], new_data: dict[str, Any]) -> None:
    old_settings, new_settings = _by_key(old_data["sources"], "name"), _by_key(new_data["sources"], "name")
    old_sources, new_sources = {s.name: s for s in old.review_segment.sources}, {s.name: s for s in new.review_segment.sources}
    for name in sorted(old_sources.keys() | new_sources.keys()):
        subject = f"source {name}"
        if name not in new_sources:
            report.add("sources", subject, "removed")
            continue
        if name not in old_sources:
            report.add("sources", subject, f"added ({new_settings[name]['kind']} {_source_files(report.new_path, new, name)[0]})")
            continue
        o, n = old_sources[name], new_sources[name]
        report.field("sources", subject, "kind", old_settings[name]["kind"], new_settings[name]["kind"])
        old_files, new_files = _source_files(report.old_path, old, name), _source_files(report.new_path, new, name)
        if len(old_files) == 1 and len(new_files) == 1:
            report.field("sources", subject, "root" if "root" in new_settings[name] else "path", old_files[0], new_files[0])
        elif not same(old_files, new_files):
            what = added_removed(old_files, new_files, ":")
            report.add(
                "sources",
                subject,
                f"files {len(old_files)} -> {len(new_files)}" + (f" ({what})" if what else ""),
                [str(f) for f in old_files],
                [str(f) for f in new_files],
            )
        both = old_settings[name].keys() & new_settings[name].keys()  # another kind's settings are its kind's change
        settings = [{key: value for key, value in side[name].items() if key in both} for side in (old_settings, new_settings)]
        report.walk("sources", subject, settings[0], settings[1], SOURCE_WORDING)
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


def _names_changes(report: Changes, subject: str, old: tuple[str, ...], new: tuple[str, ...]) -> None:
    if old == new:
        return
    changed = added_removed(old, new)
    what = f"names: {changed}" if changed else f"names reordered: {value_text(old)} -> {value_text(new)}"
    report.add("sources", subject, what, list(old), list(new))


# ---------------------------------------------------------------------------------------------------------- output


def _output_changes(report: Changes, old: Plan, new: Plan, old_data: dict[str, Any], new_data: dict[str, Any]) -> None:
    subject = "output"
    report.walk("output", subject, old_data, new_data, OUTPUT_WORDING)
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
        changed = added_removed(old_ids, new_ids, limit=5)
        report.add("output", subject, f"segments {len(old_ids)} -> {len(new_ids)} ({changed})", old_ids, new_ids)
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

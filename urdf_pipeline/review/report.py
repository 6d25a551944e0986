"""An account of a plan, for `urdf-pipeline plan` and pull-request review.

`text` (describe_plan) is the free-form account. `markdown` and `json` render one structured report (build_report),
meant for a PR comment: the same bytes for the same inputs (paths relative to the config's folder, no time, numbers
rounded to 9 decimals, order fixed: config order where it means something, tree order for edges, names otherwise),
so golden files pin it. None of it reads joint values, except `--sample` (check.read_sample); none imports Rerun
otherwise.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ConfigWarning, collect_warnings
from ..plan import IndexPlan, Plan, RobotPlan, SourcePlan
from ..urdf.model import Joint, UrdfModel, parse_urdf_text
from .report_markdown import JOINT_TYPES, render_markdown
from .report_text import describe_plan

if TYPE_CHECKING:
    from .check import JointReport


# --- the structured report: `plan --format markdown|json` -------------------------------------------------------------

REPORT_VERSION = 1
ARROWS = {  # mermaid link per edge origin
    "urdf_moving_joint": "-->",
    "urdf_fixed_joint": "-.->",
    "calibration_inline": "==>|calibration|",
    "calibration_file": "==>|calibration|",
    "fixed_chain": "==>|fixed chain|",
    "assumed_identity": "-.->|assumed identity|",
    "temporal": "==>|temporal|",
}


@dataclass(frozen=True)
class Sample:
    """What `plan --sample` read: the first `rows` rows (at most) of each robot source of the first segment."""

    rows: int
    read: dict[str, int]  # source name -> rows actually read
    reports: tuple[JointReport, ...]


def plan_command(config: Path, output_format: str, sample_rows: int | None) -> str:
    """The bytes `urdf-pipeline plan` prints. Warnings go to stderr as usual, and (markdown, json) into the report."""
    from ..compile.compiler import compile_config

    if output_format == "text":
        plan = compile_config(config)
        sample = read_plan_sample(plan, sample_rows) if sample_rows is not None else None
        return describe_plan(plan) + ("\n" + _sample_text(sample) if sample is not None else "") + "\n"
    warnings: list[ConfigWarning] = []
    try:
        with collect_warnings() as warnings:
            plan = compile_config(config)
    finally:
        for warning in warnings:
            print(warning.line(), file=sys.stderr)
    sample = read_plan_sample(plan, sample_rows) if sample_rows is not None else None
    report = build_report(plan, warnings, sample)
    return render_json(report) if output_format == "json" else render_markdown(report)


def read_plan_sample(plan: Plan, rows: int) -> Sample:
    """check.read_sample on every robot source of the plan (the first segment's), then check's per-joint verdict."""
    from .check import check_plan, read_sample

    matrices = {source.name: read_sample(source, rows) for source in plan.sources if plan.robots_for(source.name)}
    return Sample(rows, {name: len(matrix) for name, matrix in matrices.items()}, tuple(check_plan(plan, matrices)))


def _sample_text(sample: Sample) -> str:
    from .check import as_text

    read = ", ".join(f"{name}: {rows}" for name, rows in sorted(sample.read.items()))
    return f"sample (at most {sample.rows} rows of each source; read {read}):\n" + as_text(list(sample.reports))


class _Paths:
    """Paths shown relative to the config's folder (as posix), whether or not either went through a symlink."""

    def __init__(self, config: Path) -> None:
        self.bases = (Path(os.path.abspath(config)).parent, config.resolve().parent)

    def __call__(self, path: Path | str) -> str:
        for candidate in (Path(os.path.abspath(path)), Path(path).resolve()):
            for base in self.bases:
                if candidate.is_relative_to(base):
                    return candidate.relative_to(base).as_posix()
        return Path(os.path.relpath(os.path.abspath(path), self.bases[0])).as_posix()


def _r(value: float) -> float:
    """Rounded to 9 decimals, -0.0 as 0.0: equal across machines whose last bits of sin/cos differ."""
    return round(float(value), 9) + 0.0


def _rs(values: Sequence[float] | None) -> list[float] | None:
    return None if values is None else [_r(v) for v in values]


def _degrees(radians: float) -> float:
    value = _r(math.degrees(radians))
    return 180.0 if value == -180.0 else value


def _rpy_deg(q: Sequence[float]) -> list[float]:
    """URDF roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) of a unit quaternion x, y, z, w, in degrees."""
    x, y, z, w = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return [_degrees(roll), _degrees(pitch), _degrees(yaw)]


def build_report(plan: Plan, warnings: Sequence[ConfigWarning] = (), sample: Sample | None = None) -> dict[str, Any]:
    """The plan as plain data (what `--format json` prints and markdown renders): no absolute path, no time."""
    paths = _Paths(plan.config_path)
    models = {robot.key: parse_urdf_text(robot.urdf_text, robot.key) for robot in plan.robots}
    observed = {(r.robot, r.source_name, r.joint): r for r in sample.reports} if sample is not None else {}
    edges = _ordered_edges(_edges(plan, models, paths), plan.root_frame)
    frames = [robot.frame_prefix + link for robot in plan.robots for link in robot.links]
    return {
        "report_version": REPORT_VERSION,
        "config": paths(plan.config_path),
        "root_frame": plan.root_frame,
        "sources": [_source(source, paths) for source in sorted(plan.sources, key=lambda s: s.name)],
        "robots": [_robot(plan, robot, models[robot.key], observed) for robot in plan.robots],
        "edges": edges,
        "frame_tree": {"root": plan.root_frame, "mermaid": _mermaid(plan.root_frame, edges, frames)},
        "output": _output(plan, paths),
        "warnings": _warnings(warnings, paths),
        "sample": None if sample is None else {"rows": sample.rows, "read": dict(sorted(sample.read.items()))},
    }


def _source(source: SourcePlan, paths: _Paths) -> dict[str, Any]:
    result: dict[str, Any] = {"kind": type(source).__name__.removesuffix("SourcePlan").lower()}
    for item in fields(source):
        value = getattr(source, item.name)
        if item.name == "where":
            continue
        if isinstance(value, Path):
            value = paths(value)
        elif isinstance(value, IndexPlan):
            value = {"column": value.column, "kind": value.kind, "unit": value.unit}
        elif isinstance(value, tuple):
            value = list(value)
        result[item.name] = value
    return result


def _robot(plan: Plan, robot: RobotPlan, model: UrdfModel, observed: dict[tuple[str, str, str], JointReport]) -> dict[str, Any]:
    counts = {kind: sum(1 for j in model.joints if j.type == kind) for kind in JOINT_TYPES}
    counts["mimic"] = sum(1 for j in model.joints if j.mimic is not None)
    source = plan.source(robot.source) if robot.source is not None and any(s.name == robot.source for s in plan.sources) else None
    mapped = {c.source_name for c in robot.channels}
    return {
        "key": robot.key,
        "robot_name": robot.robot_name,
        "urdf": {"origin": robot.urdf_origin, "sha256": robot.urdf_sha256},
        "entity_path_prefix": robot.entity_path_prefix,
        "frame_prefix": robot.frame_prefix,
        "root_frame": robot.frame_prefix + robot.root_link,
        "collision_geometries": "keep" if robot.keep_collisions else "drop",
        "source": robot.source,
        "nan_policy": robot.nan_policy if robot.source is not None else None,
        "on_violation": robot.on_violation if robot.source is not None else None,
        "joint_counts": counts,
        "joints": _joint_rows(robot, model, observed),
        "ignored_source_values": [name for name in source.names if name not in mapped] if source is not None else [],
    }


def _row(kind: str, joint: Joint, **values: Any) -> dict[str, Any]:
    row: dict[str, Any] = {
        "kind": kind,
        "source_name": None,
        "source_index": None,
        "joint": joint.name,
        "type": joint.type,
        "unit": "rad" if joint.angular else "m",
        "sign": None,
        "offset": None,
        "scale": None,
        "wrap": None,
        "source_range": None,
        "target_range": None,
        "limits_source_units": None,
        "slack_source_units": None,
        "limits_urdf": [_r(joint.lower), _r(joint.upper)] if joint.has_limits else None,  # type: ignore[arg-type]
        "mimic": None,
        "hold": None,
        "observed": None,
    }
    row.update(values)
    return row


def _joint_rows(robot: RobotPlan, model: UrdfModel, observed: dict[tuple[str, str, str], JointReport]) -> list[dict[str, Any]]:
    joints = {joint.name: joint for joint in model.joints}
    rows = []
    for c in robot.channels:
        ranged = c.source_range is not None
        limits = c.limits_in_source_unit
        report = observed.get((robot.key, c.source_name, c.joint))
        rows.append(
            _row(
                "mapped",
                joints[c.joint],
                source_name=c.source_name,
                source_index=c.source_index,
                unit=None if ranged else c.source_unit,
                sign=None if ranged else _r(c.sign),
                offset=None if ranged else _r(c.offset),
                scale=None if ranged else _r(c.scale),
                wrap={"period": _r(c.wrap), "center": _r(c.wrap_center)} if c.wrap else None,
                source_range=_rs(c.source_range),
                target_range=_rs(c.target_range),
                limits_source_units=_rs(limits),
                slack_source_units=_r(slack) if limits is not None and (slack := c.slack_in_source_unit) is not None else None,
                observed=_observed(report) if report is not None else None,
            )
        )
    rows += [_row("held", joints[h.joint], hold=_r(h.value)) for h in robot.holds]
    rows += [
        _row("mimic", joints[m.joint], mimic={"driver": m.driver, "multiplier": _r(m.multiplier), "offset": _r(m.offset)})
        for m in robot.mimics
    ]
    return rows


def _observed(report: JointReport) -> dict[str, Any]:
    return {
        "rows": report.rows,
        "min": None if report.raw_min is None else _r(report.raw_min),
        "max": None if report.raw_max is None else _r(report.raw_max),
        "fits": report.current_fits,
        "verdict": report.verdict,
        "slack_rows": report.slack_rows,
    }


def _origin(kind: str, description: str, **values: Any) -> dict[str, Any]:
    origin: dict[str, Any] = {"kind": kind, "description": description, "robot": None, "joint": None, "joint_type": None}
    origin.update({"file": None, "line": None, "label": None, "source": None, "fixed_chain": None})
    origin.update(values)
    return origin


def _edge(
    parent: str, child: str, origin: dict[str, Any], translation: Sequence[float] | None, rpy_deg: list[float] | None
) -> dict[str, Any]:
    return {
        "parent": parent,
        "child": child,
        "translation_m": _rs(translation),
        "rotation_rpy_deg": rpy_deg,
        "temporal": None,
        "origin": origin,
    }


def _edges(plan: Plan, models: dict[str, UrdfModel], paths: _Paths) -> list[dict[str, Any]]:
    """Every edge of the frame graph: each URDF joint (moving ones at their origin), each configured edge."""
    driven = {(t.parent, t.child) for t in plan.temporal_edges}
    overridden: dict[tuple[str, str], str] = {}
    edges = []
    for robot in plan.robots:
        prefix = robot.frame_prefix
        for joint in models[robot.key].joints:
            parent, child = prefix + joint.parent, prefix + joint.child
            if joint.type in ("floating", "planar") and (parent, child) in driven:  # as frame_edges: the temporal edge wins
                overridden[(parent, child)] = f"; overrides URDF {joint.type} joint {joint.name} of robot {robot.key}"
                continue
            if joint.type == "fixed":
                kind, description = "urdf_fixed_joint", f"URDF fixed joint {joint.name} of robot {robot.key}"
            else:
                kind, description = "urdf_moving_joint", f"URDF moving joint {joint.name} ({joint.type}) of robot {robot.key}"
            origin = _origin(kind, description, robot=robot.key, joint=joint.name, joint_type=joint.type)
            edges.append(_edge(parent, child, origin, joint.xyz, [_degrees(v) for v in joint.rpy]))
    config = os.path.abspath(plan.config_path)
    for edge in plan.edges:
        file, line, label = paths(edge.where.file), edge.where.line, edge.label
        inline = os.path.abspath(edge.where.file) == config
        place = f"{label}, line {line}" if inline else f"{file}:{line}"
        common = {"file": file, "line": line, "label": label}
        if edge.kind == "fixed_chain" and edge.fixed_chain is not None:
            chain = edge.fixed_chain
            joints = ", ".join(chain.joints) or "no joint: from and to are the same link"
            description = f"fixed chain {chain.start} -> {chain.end} of robot {chain.robot} (fixed joints {joints}; {place})"
            origin = _origin("fixed_chain", description, robot=chain.robot, fixed_chain=list(chain.joints), **common)
        elif edge.kind == "assume_identity":
            origin = _origin("assumed_identity", f"assumed identity, not calibrated ({place})", **common)
        elif inline:
            origin = _origin("calibration_inline", f"calibration inline ({place})", **common)
        else:
            origin = _origin("calibration_file", f"calibration file {place}", **common)
        edges.append(_edge(edge.parent, edge.child, origin, edge.translation, _rpy_deg(edge.quaternion_xyzw)))
    for temporal in plan.temporal_edges:
        file, line = paths(temporal.where.file), temporal.where.line
        place = f"{temporal.label}, line {line}" if os.path.abspath(temporal.where.file) == config else f"{file}:{line}"
        description = f"temporal edge from source {temporal.source} ({place}{overridden.get((temporal.parent, temporal.child), '')})"
        origin = _origin("temporal", description, file=file, line=line, label=temporal.label, source=temporal.source)
        edge_data = _edge(temporal.parent, temporal.child, origin, None, None)
        edge_data["temporal"] = {
            "source": temporal.source,
            "entity": temporal.entity,
            "translation_names": list(temporal.translation_names),
            "translation_indices": list(temporal.translation_indices),
            "quaternion_xyzw_names": list(temporal.quaternion_names),
            "quaternion_xyzw_indices": list(temporal.quaternion_indices),
        }
        edges.append(edge_data)
    return edges


def _ordered_edges(edges: list[dict[str, Any]], root: str) -> list[dict[str, Any]]:
    """Depth first from the root, children by name: the frame tree read top down. Edges not reached (none in a valid
    plan) follow, by parent and child."""
    children: dict[str, list[dict[str, Any]]] = {}
    for edge in sorted(edges, key=lambda e: (e["child"], e["parent"])):
        children.setdefault(edge["parent"], []).append(edge)
    ordered: list[dict[str, Any]] = []
    visited = {root}
    stack = list(reversed(children.get(root, [])))
    while stack:
        edge = stack.pop()
        ordered.append(edge)
        if edge["child"] not in visited:
            visited.add(edge["child"])
            stack.extend(reversed(children.get(edge["child"], [])))
    placed = {id(edge) for edge in ordered}
    return ordered + sorted((e for e in edges if id(e) not in placed), key=lambda e: (e["parent"], e["child"]))


def _mermaid_label(frame: str) -> str:
    """A frame name inside a quoted mermaid label: characters mermaid would read as syntax become entity codes."""
    text = frame.replace("#", "#35;")
    for char, code in (('"', "#quot;"), ("<", "#lt;"), (">", "#gt;"), ("`", "#96;"), ("|", "#124;")):
        text = text.replace(char, code)
    return text


def _mermaid(root: str, edges: list[dict[str, Any]], frames: list[str]) -> str:
    """`graph TD` of the frame tree. Node ids are f0 (the root), f1, ... in tree order; labels are the frame names."""
    ids: dict[str, str] = {}
    for frame in [root, *(f for e in edges for f in (e["parent"], e["child"])), *sorted(frames)]:
        ids.setdefault(frame, f"f{len(ids)}")
    lines = ["graph TD"]
    lines += [f'  {ident}["{_mermaid_label(frame)}"]' for frame, ident in ids.items()]
    lines += [f"  {ids[e['parent']]} {ARROWS[e['origin']['kind']]} {ids[e['child']]}" for e in edges]
    return "\n".join(lines)


def _output(plan: Plan, paths: _Paths) -> dict[str, Any]:
    dataset = plan.dataset
    if dataset is None:  # plans built by hand in tests
        segment = {"id": plan.output.recording_id, "episode": None, "stem": None, "frames": None, "output": paths(plan.output.path)}
        return {
            "layout": "single",
            "application_id": plan.output.application_id,
            "segment_count": 1,
            "segments": [segment],
            "model": None,
            "manifest": None,
        }
    segments = [{"id": s.id, "episode": s.episode, "stem": s.stem, "frames": s.frames, "output": paths(s.output)} for s in dataset.segments]
    return {
        "layout": dataset.layout,
        "application_id": plan.output.application_id,
        "segment_count": len(segments),
        "segments": segments,
        "model": paths(dataset.model) if dataset.model is not None else None,
        "manifest": paths(dataset.manifest),
    }


def _warnings(warnings: Sequence[ConfigWarning], paths: _Paths) -> list[dict[str, Any]]:
    items = {}
    for warning in warnings:
        where = warning.where
        item = {
            "file": paths(where.file) if where is not None else None,
            "line": where.line if where is not None else 0,
            "column": where.column if where is not None and where.line else 0,
            "path": where.path if where is not None else "",
            "message": warning.message,
        }
        items[json.dumps(item, sort_keys=True)] = item
    return sorted(items.values(), key=lambda i: (i["file"] or "", i["line"], i["column"], i["path"], i["message"]))


def render_json(report: dict[str, Any]) -> str:
    return json.dumps(report, indent=2, sort_keys=True) + "\n"


# --- markdown ----------------------------------------------------------------------------------------------------------

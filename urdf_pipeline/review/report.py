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
from ..plan import IndexPlan, JointChannel, Plan, RobotPlan, SourcePlan
from ..urdf.model import Joint, UrdfModel, parse_urdf_text

if TYPE_CHECKING:
    from .check import JointReport


def _channel_text(c: JointChannel) -> str:
    steps = [f"wrap {c.wrap:g} around {c.wrap_center:g}"] if c.wrap else []
    if c.source_range is not None and c.target_range is not None:
        steps.append(f"source_range {list(c.source_range)} onto {[round(v, 9) for v in c.target_range]}")
    else:
        steps.append(f"x {c.factor:g} ({c.source_unit})" + (f" x {c.scale:g}" if c.scale != 1 else "") + f" x {c.sign:g} + {c.offset:g}")
    source = c.limits_in_source_unit
    if source is None:
        steps.append("limits none")
    else:
        unit = "source units" if c.source_range is not None else c.source_unit
        steps.append(
            f"limits {source[0]:.6g} .. {source[1]:.6g} {unit} (URDF [{c.lower:g}, {c.upper:g}]), slack {c.slack_in_source_unit or 0:g} {unit}"
        )
    return "; ".join(steps)


def _robot_lines(robot: RobotPlan) -> list[str]:
    lines = [
        f"robot {robot.key}: URDF '{robot.robot_name}' from {robot.urdf_path}",
        f"  entity {robot.entity_path_prefix}, frame prefix '{robot.frame_prefix}', root link {robot.frame_prefix}{robot.root_link}, collisions {'kept' if robot.keep_collisions else 'dropped'}",
    ]
    if robot.source is None:
        return [*lines, "  a scene: no moving joints, no joint source (static transforms only)"]
    lines += [
        f"  joints from source '{robot.source}', NaN policy {robot.nan_policy}; per value, in this order:",
        "    wrap (source units) -> (value * unit factor * scale) * sign + offset, or source_range onto the joint's range"
        " -> limits (clamp within slack) -> mimic joints",
    ]
    for c in robot.channels:
        lines.append(f"    {c.source_name}[{c.source_index}] -> {c.joint}: {_channel_text(c)}")
    lines += [f"    hold {h.joint} = {h.value:g}" for h in robot.holds]
    lines += [f"    mimic {m.joint} = {m.driver} * {m.multiplier:g} + {m.offset:g}" for m in robot.mimics]
    lines.append(f"  beyond-slack values: {robot.on_violation}")
    return lines


def _edge_lines(plan: Plan) -> list[str]:
    lines = []
    for edge in plan.edges:
        pose = f"t={[round(v, 9) for v in edge.translation]} q_xyzw={[round(v, 9) for v in edge.quaternion_xyzw]}"
        origin = f" ({edge.label}, line {edge.where.line})" if edge.label else ""
        if edge.kind == "fixed_chain" and edge.fixed_chain is not None:
            chain = edge.fixed_chain
            joints = ", ".join(chain.joints) or "none: from and to are the same link"
            lines.append(f"edge {edge.parent} -> {edge.child}: fixed chain {chain.start} -> {chain.end} of robot {chain.robot}{origin}")
            lines.append(f"  fixed joints composed: {joints}; {pose}")
        elif edge.kind == "assume_identity":
            lines.append(f"edge {edge.parent} -> {edge.child}: identity ASSUMED, not calibrated{origin}")
        else:
            lines.append(f"edge {edge.parent} -> {edge.child}: {pose}{origin}")
    for temporal in plan.temporal_edges:
        lines.append(
            f"temporal edge {temporal.parent} -> {temporal.child} on {temporal.entity} ({temporal.label}, "
            f"line {temporal.where.line}): per row of source '{temporal.source}', "
            f"translation {_named(temporal.translation_names, temporal.translation_indices)}, "
            f"quaternion_xyzw {_named(temporal.quaternion_names, temporal.quaternion_indices)} (normalised per row)"
        )
    return lines


def _named(names: tuple[str, ...], indices: tuple[int, ...]) -> str:
    return "[" + ", ".join(f"{name}[{index}]" for name, index in zip(names, indices, strict=True)) + "]"


def describe_plan(plan: Plan) -> str:
    lines = [f"config {plan.config_path}", f"root frame: {plan.root_frame}"]
    for source in plan.sources:
        lines.append(f"source {source.name}: {type(source).__name__.removesuffix('SourcePlan').lower()} with {len(source.names)} names")
    for robot in plan.robots:
        lines += _robot_lines(robot)
    lines += _edge_lines(plan)
    lines += _output_lines(plan)
    return "\n".join(lines)


def _output_lines(plan: Plan) -> list[str]:
    if plan.dataset is None or len(plan.segments) == 1 and plan.dataset.layout == "single":
        return [f"output {plan.output.path} (application_id {plan.output.application_id}, recording_id {plan.output.recording_id})"]
    dataset, segments = plan.dataset, plan.segments
    named = ", ".join(s.id for s in segments[:3]) + (f", ... {segments[-1].id}" if len(segments) > 3 else "")
    lines = [f"output: {len(segments)} segments ({named}), layout {dataset.layout}, application_id {plan.output.application_id}"]
    if dataset.model is not None:
        lines.append(f"  model (meshes, static URDF transforms, written once, static only): {dataset.model}")
    what = "layer (forward kinematics, calibration edges)" if dataset.layout == "split" else "recording"
    lines.append(f"  each segment's {what}: {segments[0].output} ... recording_id = segment id")
    lines.append(f"  manifest: {dataset.manifest}")
    return lines


# --- the structured report: `plan --format markdown|json` -------------------------------------------------------------

REPORT_VERSION = 1
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
MARKDOWN_SEGMENTS = 20  # segment rows shown in markdown; json lists them all
DASH = "—"
ORDER_NOTE = (
    "Per source value, in this order: wrap (source units) → value × unit factor × scale × sign + offset (offset in URDF "
    "units), or source_range mapped onto the joint's range → limits (clamped within the slack) → mimic joints. "
    "Limits in source units are the raw values these corrections send onto the URDF limits, low to high (as "
    "`urdf-pipeline check` and a run's limit error show them)."
)
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


def _n(value: float) -> str:
    return f"{value:.6g}"


def _ns(values: Sequence[float]) -> str:
    return ", ".join(_n(v) for v in values)


def _code(text: str) -> str:
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(cell.replace("|", "\\|").replace("\n", " ") for cell in cells) + " |"

    return [line(header), line(["---"] * len(header)), *(line(row) for row in rows)]


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def _source_details(source: dict[str, Any]) -> str:
    parts = []
    for key in sorted(source):
        if key in ("name", "kind", "path", "root", "names"):
            continue
        value = source[key]
        if isinstance(value, dict):  # an index
            value = f"{value['column']} ({value['kind']}{', ' + value['unit'] if value['unit'] else ''})"
        elif isinstance(value, bool):
            value = "yes" if value else "no"
        elif value is None:
            value = "row_index (generated)" if key == "index" else DASH
        parts.append(f"{key}: {value}")
    return "; ".join(parts)


def _map_cell(row: dict[str, Any]) -> str:
    parts = []
    if row["wrap"] is not None:
        parts.append(f"wrap {_n(row['wrap']['period'])} around {_n(row['wrap']['center'])}")
    if row["source_range"] is not None:
        parts.append(f"source_range [{_ns(row['source_range'])}] → [{_ns(row['target_range'])}]")
    elif row["scale"] is not None and row["scale"] != 1:
        parts.append(f"× {_n(row['scale'])}")
    return "; ".join(parts) or DASH


def _limits_cell(row: dict[str, Any]) -> str:
    if row["kind"] != "mapped":
        return DASH
    if row["limits_source_units"] is None:
        return "none"
    low, high = row["limits_source_units"]
    slack = row["slack_source_units"]
    return f"{_n(low)} .. {_n(high)}" + (f" ± {_n(slack)}" if slack else "")


def _driver_cell(row: dict[str, Any]) -> str:
    if row["kind"] == "held":
        return f"`hold = {_n(row['hold'])}`"
    if row["kind"] == "mimic":
        mimic = row["mimic"]
        return f"{_code(mimic['driver'])} × {_n(mimic['multiplier'])} + {_n(mimic['offset'])}"
    return DASH


def _observed_cell(observed: dict[str, Any] | None) -> str:
    if observed is None:
        return DASH
    if observed["min"] is None:
        return f"no finite values in {observed['rows']} rows"
    if observed["verdict"] == "no limits":
        status = "no limits"
    elif not observed["fits"]:
        status = "**outside the limits**"
    elif observed["slack_rows"]:
        status = f"fits; {observed['slack_rows']} rows within the slack"
    else:
        status = "fits"
    return f"{_n(observed['min'])} .. {_n(observed['max'])} ({status})"


def _robot_markdown(robot: dict[str, Any], sample: dict[str, Any] | None) -> list[str]:
    counts = robot["joint_counts"]
    prefix = _code(robot["frame_prefix"]) if robot["frame_prefix"] else "none"
    lines = [
        f"#### Robot {_code(robot['key'])}: URDF {_code(robot['robot_name'])}",
        "",
        f"- URDF: {_code(robot['urdf']['origin'])}, sha256 {_code(robot['urdf']['sha256'])}",
        f"- entity path {_code(robot['entity_path_prefix'])}, frame prefix {prefix}, root frame {_code(robot['root_frame'])}, "
        f"collision geometries {'kept' if robot['collision_geometries'] == 'keep' else 'dropped'}",
        "- URDF joints: " + ", ".join(f"{counts[kind]} {kind}" for kind in JOINT_TYPES) + f"; {counts['mimic']} mimic",
    ]
    if robot["source"] is None:
        return [*lines, "- a scene: no moving joints, no joint source (static transforms only)", ""]
    lines.append(
        f"- joints from source {_code(robot['source'])}; NaN policy {_code(robot['nan_policy'])}; "
        f"values beyond the slack: {_code(robot['on_violation'])}"
    )
    ignored = robot["ignored_source_values"]
    lines.append("- ignored source values: " + (", ".join(_code(name) for name in ignored) if ignored else "none"))
    if sample is not None:
        read = sample["read"].get(robot["source"], 0)
        lines.append(f"- sampled: the first {_plural(read, 'row')} of source {_code(robot['source'])} (at most {sample['rows']})")
    header = [
        "source name", "URDF joint", "type", "unit", "sign", "offset (URDF units)", "scale / range map", "limits (source units)", "mimic driver / hold",
    ]  # fmt: skip
    if sample is not None:
        header.append("observed (source units)")
    rows = []
    for row in robot["joints"]:
        cells = [
            _code(row["source_name"]) if row["source_name"] is not None else DASH,
            _code(row["joint"]),
            row["type"],
            row["unit"] or DASH,
            _n(row["sign"]) if row["sign"] is not None else DASH,
            _n(row["offset"]) if row["offset"] is not None else DASH,
            _map_cell(row),
            _limits_cell(row),
            _driver_cell(row),
        ]
        if sample is not None:
            cells.append(_observed_cell(row["observed"]))
        rows.append(cells)
    return [*lines, "", *_table(header, rows), ""]


def _edge_cells(edge: dict[str, Any]) -> list[str]:
    temporal = edge["temporal"]
    if temporal is not None:
        translation = "per row: " + ", ".join(_code(n) for n in temporal["translation_names"])
        rotation = "per row: quaternion_xyzw " + ", ".join(_code(n) for n in temporal["quaternion_xyzw_names"])
    else:
        translation, rotation = _ns(edge["translation_m"]), _ns(edge["rotation_rpy_deg"])
    return [_code(edge["parent"]), _code(edge["child"]), translation, rotation, edge["origin"]["description"]]


def _output_markdown(output: dict[str, Any]) -> list[str]:
    lines = ["#### Output", "", f"- layout {_code(output['layout'])}, application_id {_code(output['application_id'])}"]
    if output["model"] is not None:
        lines.append(f"- model (meshes, static URDF transforms, written once, static only): {_code(output['model'])}")
    if output["manifest"] is not None:
        lines.append(f"- manifest: {_code(output['manifest'])}")
    what = "layer (forward kinematics, calibration edges)" if output["layout"] == "split" else "recording"
    lines.append(f"- {_plural(output['segment_count'], 'segment')}, each a {what} whose recording_id is the segment id:")
    rows = []
    for segment in output["segments"][:MARKDOWN_SEGMENTS]:
        source = f"episode {segment['episode']}" if segment["episode"] is not None else ""
        if segment["stem"] is not None:
            source = f"file {segment['stem']}" + (f" ({source})" if source else "")
        frames = str(segment["frames"]) if segment["frames"] is not None else DASH
        rows.append([_code(segment["id"]), source or DASH, frames, _code(segment["output"])])
    hidden = output["segment_count"] - len(rows)
    if hidden > 0:
        rows.append([f"… {hidden} more", "", "", ""])
    return [*lines, "", *_table(["segment", "input", "frames", "output"], rows), ""]


def render_markdown(report: dict[str, Any]) -> str:
    edges, robots, sources = report["edges"], report["robots"], report["sources"]
    configured = sum(1 for e in edges if not e["origin"]["kind"].startswith("urdf_"))
    segments = report["output"]["segment_count"]
    lines = [
        f"### urdf-pipeline plan: {_code(report['config'])}",
        "",
        f"Root frame {_code(report['root_frame'])}; {_plural(len(robots), 'robot')}, {_plural(len(sources), 'source')}, "
        f"{_plural(len(edges), 'edge')} ({configured} from the config, {len(edges) - configured} URDF joints), "
        f"{_plural(segments, 'segment')}.",
        "",
        "#### Sources" + (" (the first segment's)" if segments > 1 else ""),
        "",
        *_table(
            ["source", "kind", "file", "reads", "values"],
            [
                [_code(s["name"]), s["kind"], _code(s.get("path", s.get("root", ""))), _source_details(s), str(len(s["names"]))]
                for s in sources
            ],
        ),
        "",
    ]
    if any(robot["joints"] for robot in robots):
        lines += [f"> {ORDER_NOTE}", ""]
    for robot in robots:
        lines += _robot_markdown(robot, report["sample"])
    lines += [
        "#### Edges",
        "",
        "Every edge of the frame graph, top down from the root. URDF moving joints are shown at their origin (joint value 0); "
        "the run logs their pose per row.",
        "",
        *_table(["parent", "child", "translation (m)", "rotation (rpy deg)", "origin"], [_edge_cells(e) for e in edges]),
        "",
        "#### Frame tree",
        "",
        "```mermaid",
        report["frame_tree"]["mermaid"],
        "```",
        "",
        "`-->` URDF moving joint, `-.->` URDF fixed joint, `==>` an edge of the config (`-.->` when its identity is assumed).",
        "",
        *_output_markdown(report["output"]),
        "#### Warnings",
        "",
    ]
    warnings = report["warnings"]
    if not warnings:
        lines.append("None.")
    for warning in warnings:
        place = warning["file"] or report["config"]
        if warning["line"]:
            place += f":{warning['line']}" + (f":{warning['column']}" if warning["column"] else "")
        lines.append(f"- {_code(place)}" + (f" {_code(warning['path'])}" if warning["path"] else "") + f": {warning['message']}")
    return "\n".join(lines) + "\n"

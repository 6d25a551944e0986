"""`urdf-pipeline plan`: the plan's report model (report_model.PlanReport), built here from the plan alone (joint
values only with `--sample`), in a fixed order, so that markdown and json are the same bytes for the same inputs."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from ...errors import ConfigWarning, collect_warnings, show_warning, shown
from ...plan import IndexPlan, Plan, QaPlan, RobotPlan, SourcePlan, TrailPlan
from ...urdf import Joint, UrdfModel, parse_urdf_text
from ..picture_entries import plan_pictures
from .report_markdown import render_markdown
from .report_model import (
    JOINT_TYPES,
    Appearance,
    Compare,
    EdgeEntry,
    EdgeOrigin,
    FrameTree,
    JointRow,
    Mimic,
    Observed,
    OriginKind,
    OutputEntry,
    PlanReport,
    QaEntry,
    RobotEntry,
    SampleEntry,
    SegmentEntry,
    SettingValue,
    ShownPath,
    Slack,
    SourceEntry,
    TemporalValues,
    TrailEntry,
    UrdfEntry,
    WarningEntry,
    Wrap,
    as_data,
    number,
    rounded,
)
from .report_text import render_text

if TYPE_CHECKING:
    from ...render import Size
    from ...web import SiteWriter
    from ..check.check_joints import JointReport

PlanFormat = Literal["text", "markdown", "json"]
ARROWS = {  # mermaid link per edge origin
    "urdf_moving_joint": "-->",
    "urdf_fixed_joint": "-.->",
    "calibration_inline": "==>|calibration|",
    "calibration_file": "==>|calibration|",
    "fixed_chain": "==>|fixed chain|",
    "assumed_identity": "-.->|assumed identity|",
    "temporal": "==>|temporal|",
}
RENDERERS = {
    "text": render_text,
    "markdown": render_markdown,
    "json": lambda report: json.dumps(as_data(report), indent=2, sort_keys=True) + "\n",  # no absolute path, no time
}


def plan_command(
    config: Path,
    output_format: PlanFormat,
    sample_rows: int | None,
    render: Path | None = None,
    size: Size | None = None,
    site: SiteWriter | None = None,
) -> str:
    """The bytes `urdf-pipeline plan` prints. Warnings go to stderr as usual, and into the report. With `render`, the
    Rerun viewer draws the rest pose into that folder first, and the report links the pictures. With `site` (`--html`),
    the report goes into it as well, as HTML with the rest pose in the web viewer (review_site.py)."""
    from ...compile import compile_config

    warnings: list[ConfigWarning] = []
    try:
        with collect_warnings() as warnings:
            plan = compile_config(config)
    finally:
        for warning in warnings:
            show_warning(warning)
    sample = read_plan_sample(plan, sample_rows) if sample_rows is not None else None
    report = build_report(plan, warnings, sample)
    if render is not None:
        report = replace(report, pictures=plan_pictures(plan, render, size))
    if site is not None:
        from ..review_site import write_plan_site

        write_plan_site(site, plan, report)
    return RENDERERS[output_format](report)


def read_plan_sample(plan: Plan, rows: int) -> SampleEntry:
    """check.plan_sample, then check's per-joint verdict."""
    from ..check.check_joints import check_plan, plan_sample

    matrices = plan_sample(plan, rows)
    return SampleEntry(rows, {name: len(matrices[name]) for name in sorted(matrices)}, tuple(check_plan(plan, matrices)))


class _Paths:
    """Paths shown relative to the config's folder (as posix), whether or not either went through a symlink."""

    def __init__(self, config: Path) -> None:
        self.bases = (Path(os.path.abspath(config)).parent, config.resolve().parent)

    def relative(self, path: Path | str) -> str:
        for candidate in (Path(os.path.abspath(path)), Path(path).resolve()):
            for base in self.bases:
                if candidate.is_relative_to(base):
                    return candidate.relative_to(base).as_posix()
        return Path(os.path.relpath(os.path.abspath(path), self.bases[0])).as_posix()

    def __call__(self, path: Path) -> ShownPath:
        return ShownPath(path, self.relative(path))


def _degrees(radians: float) -> float:
    value = rounded(math.degrees(radians))
    return 180.0 if value == -180.0 else value


def _rpy_deg(q: Sequence[float]) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) of a unit quaternion x, y, z, w, in degrees."""
    x, y, z, w = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return (_degrees(roll), _degrees(pitch), _degrees(yaw))


def build_report(plan: Plan, warnings: Sequence[ConfigWarning] = (), sample: SampleEntry | None = None) -> PlanReport:
    """The plan as the report model: everything any format shows, nothing absolute that markdown or json print."""
    paths = _Paths(plan.config_path)
    models = {robot.key: parse_urdf_text(robot.urdf_text, robot.key) for robot in plan.robots}
    observed = {(r.robot, r.source_name, r.joint): r for r in sample.reports} if sample is not None else {}
    urdf_edges, configured = _edges(plan, models, paths)
    edges = _ordered_edges([*urdf_edges, *configured], plan.root_frame)
    frames = [robot.frame_prefix + link for robot in plan.robots for link in robot.links]
    return PlanReport(
        config=paths(plan.config_path),
        root_frame=plan.root_frame,
        sources=tuple(_source(source, paths) for source in plan.review_segment.sources),
        robots=tuple(_robot(plan, robot, models[robot.key], observed) for robot in plan.robots),
        edges=tuple(edges),
        configured_edges=tuple(configured),
        frame_tree=FrameTree(plan.root_frame, _mermaid(plan.root_frame, edges, frames)),
        output=_output(plan, paths),
        warnings=_warnings(warnings, paths),
        sample=sample,
        qa=_qa(plan.qa) if plan.qa != QaPlan() else None,
    )


def _qa(qa: QaPlan) -> QaEntry:
    gap = f"{qa.gap_seconds * 1000:g} ms" if qa.gap_seconds is not None else f"{qa.gap_steps:g} steps"
    jerk = qa.spike_jerk.text if qa.spike_jerk is not None else None
    return QaEntry(qa.static_velocity.text, qa.spike_factor, jerk, gap, qa.length_iqr, qa.bias.text, qa.fail_on)


def _source(source: SourcePlan, paths: _Paths) -> SourceEntry:
    file_key = "root" if hasattr(source, "root") else "path"
    settings: dict[str, SettingValue] = {}
    for item in sorted(fields(source), key=lambda item: item.name):
        value = getattr(source, item.name)
        if item.name in ("name", "where", "names", file_key, "remote", "fps", "timed"):  # fps, timed: the dataset's, not settings
            continue
        assert value is None or isinstance(value, str | int | bool | IndexPlan), f"{item.name}: {value!r}"
        settings[item.name] = value
    return SourceEntry(
        source.name,
        type(source).__name__.removesuffix("SourcePlan").lower(),
        file_key,
        ShownPath(getattr(source, file_key), remote.url)
        if (remote := getattr(source, "remote", None)) is not None
        else paths(getattr(source, file_key)),
        tuple(source.names),
        settings,
    )


def _robot(plan: Plan, robot: RobotPlan, model: UrdfModel, observed: dict[tuple[str, str, str], JointReport]) -> RobotEntry:
    counts = {kind: sum(1 for j in model.joints if j.type == kind) for kind in JOINT_TYPES}
    counts["mimic"] = sum(1 for j in model.joints if j.mimic is not None)
    source = next((s for s in plan.review_segment.sources if s.name == robot.source), None)
    mapped = {c.source_name for c in robot.channels}
    return RobotEntry(
        key=robot.key,
        robot_name=robot.robot_name,
        urdf_path=robot.urdf_path,
        urdf=UrdfEntry(robot.urdf_origin, robot.urdf_sha256),
        entity_path_prefix=robot.entity_path_prefix,
        frame_prefix=robot.frame_prefix,
        root_frame=robot.frame_prefix + robot.root_link,
        collision_geometries="keep" if robot.keep_collisions else "drop",
        source=robot.source,
        nan_policy=robot.nan_policy if robot.source is not None else None,
        on_violation=robot.on_violation if robot.source is not None else None,
        joint_counts=counts,
        joints=_joint_rows(robot, model, observed),
        ignored_source_values=tuple(name for name in source.names if name not in mapped) if source is not None else (),
        appearance=Appearance(robot.appearance[:3], robot.appearance[3]) if robot.appearance is not None else None,
        compare=Compare(robot.compare.robot, robot.compare.written) if robot.compare is not None else None,
    )


def _limits_urdf(joint: Joint) -> tuple[float, float] | None:
    return (joint.lower, joint.upper) if joint.has_limits and joint.lower is not None and joint.upper is not None else None


def _joint_rows(robot: RobotPlan, model: UrdfModel, observed: dict[tuple[str, str, str], JointReport]) -> tuple[JointRow, ...]:
    joints = {joint.name: joint for joint in model.joints}
    rows = []
    for c in robot.channels:
        joint, ranged = joints[c.joint], c.source_range is not None
        limits = c.limits_in_source_unit
        report = observed.get((robot.key, c.source_name, c.joint))
        rows.append(
            JointRow(
                "mapped",
                joint.name,
                joint.type,
                None if ranged else c.source_unit,
                _limits_urdf(joint),
                source_name=c.source_name,
                source_index=c.source_index,
                factor=None if ranged else c.factor,
                sign=None if ranged else c.sign,
                offset=None if ranged else c.offset,
                scale=None if ranged else c.scale,
                wrap=Wrap(c.wrap, c.wrap_center) if c.wrap else None,
                source_range=c.source_range,
                target_range=c.target_range,
                limits_source_units=limits,
                slack_source_units=c.slack_in_source_unit if limits is not None else None,
                slack=Slack(*c.slack_written) if limits is not None else None,
                observed=_observed(report) if report is not None else None,
            )
        )
    for held in robot.holds:
        joint = joints[held.joint]
        rows.append(JointRow("held", joint.name, joint.type, _urdf_unit(joint), _limits_urdf(joint), hold=held.value))
    for m in robot.mimics:
        joint = joints[m.joint]
        mimic = Mimic(m.driver, m.multiplier, m.offset)
        rows.append(JointRow("mimic", joint.name, joint.type, _urdf_unit(joint), _limits_urdf(joint), mimic=mimic))
    return tuple(rows)


def _urdf_unit(joint: Joint) -> str:
    return "rad" if joint.angular else "m"


def _observed(report: JointReport) -> Observed:
    return Observed(report.rows, report.raw_min, report.raw_max, report.current_fits, report.verdict, report.slack_rows)


def _edges(plan: Plan, models: dict[str, UrdfModel], paths: _Paths) -> tuple[list[EdgeEntry], list[EdgeEntry]]:
    """Every edge of the frame graph: each URDF joint (moving ones at their origin); each configured edge, config order."""
    driven = {(t.parent, t.child) for t in plan.temporal_edges}
    overridden: dict[tuple[str, str], str] = {}
    urdf_edges = []
    for robot in plan.robots:
        prefix = robot.frame_prefix
        for joint in models[robot.key].joints:
            parent, child = prefix + joint.parent, prefix + joint.child
            if joint.type in ("floating", "planar") and (parent, child) in driven:  # as frame_edges: the temporal edge wins
                overridden[(parent, child)] = f"; overrides URDF {joint.type} joint {joint.name} of robot {robot.key}"
                continue
            kind: OriginKind
            if joint.type == "fixed":
                kind, description = "urdf_fixed_joint", f"URDF fixed joint {joint.name} of robot {robot.key}"
            else:
                kind, description = "urdf_moving_joint", f"URDF moving joint {joint.name} ({joint.type}) of robot {robot.key}"
            origin = EdgeOrigin(kind, description, robot=robot.key, joint=joint.name, joint_type=joint.type)
            urdf_edges.append(EdgeEntry(parent, child, origin, joint.xyz, tuple(_degrees(v) for v in joint.rpy)))
    config = os.path.abspath(plan.config_path)
    configured = []
    for edge in plan.edges:
        file, line, label = paths.relative(edge.where.file), edge.where.line, edge.label
        inline = os.path.abspath(edge.where.file) == config
        place = f"{label}, line {line}" if inline else f"{file}:{line}"
        if edge.kind == "fixed_chain" and edge.fixed_chain is not None:
            chain = edge.fixed_chain
            joints = ", ".join(chain.joints) or "no joint: from and to are the same link"
            description = f"fixed chain {chain.start} -> {chain.end} of robot {chain.robot} (fixed joints {joints}; {place})"
            origin = EdgeOrigin("fixed_chain", description, robot=chain.robot, file=file, line=line, label=label, fixed_chain=chain)
        elif edge.kind == "assume_identity":
            origin = EdgeOrigin("assumed_identity", f"assumed identity, not calibrated ({place})", file=file, line=line, label=label)
        elif inline:
            origin = EdgeOrigin("calibration_inline", f"calibration inline ({place})", file=file, line=line, label=label)
        else:
            origin = EdgeOrigin("calibration_file", f"calibration file {place}", file=file, line=line, label=label)
        rpy = _rpy_deg(edge.quaternion_xyzw)
        configured.append(EdgeEntry(edge.parent, edge.child, origin, edge.translation, rpy, quaternion_xyzw=edge.quaternion_xyzw))
    for temporal in plan.temporal_edges:
        file, line = paths.relative(temporal.where.file), temporal.where.line
        place = f"{temporal.label}, line {line}" if os.path.abspath(temporal.where.file) == config else f"{file}:{line}"
        description = f"temporal edge from source {temporal.source} ({place}{overridden.get((temporal.parent, temporal.child), '')})"
        origin = EdgeOrigin("temporal", description, file=file, line=line, label=temporal.label, source=temporal.source)
        values = TemporalValues(**{item.name: getattr(temporal, item.name) for item in fields(TemporalValues)})  # the plan's, by name
        configured.append(EdgeEntry(temporal.parent, temporal.child, origin, None, None, temporal=values))
    return urdf_edges, configured


def _ordered_edges(edges: list[EdgeEntry], root: str) -> list[EdgeEntry]:
    """Depth first from the root, children by name: the frame tree read top down. Edges not reached (none in a valid
    plan) follow, by parent and child."""
    children: dict[str, list[EdgeEntry]] = {}
    for edge in sorted(edges, key=lambda e: (e.child, e.parent)):
        children.setdefault(edge.parent, []).append(edge)
    ordered: list[EdgeEntry] = []
    visited = {root}
    stack = list(reversed(children.get(root, [])))
    while stack:
        edge = stack.pop()
        ordered.append(edge)
        if edge.child not in visited:
            visited.add(edge.child)
            stack.extend(reversed(children.get(edge.child, [])))
    placed = {id(edge) for edge in ordered}
    return ordered + sorted((e for e in edges if id(e) not in placed), key=lambda e: (e.parent, e.child))


def _mermaid_label(frame: str) -> str:
    """A frame name inside a quoted mermaid label: characters mermaid would read as syntax become entity codes."""
    text = shown(frame).replace("#", "#35;")  # one line, bounded: a newline would end the mermaid line
    for char, code in (('"', "#quot;"), ("<", "#lt;"), (">", "#gt;"), ("`", "#96;"), ("|", "#124;")):
        text = text.replace(char, code)
    return text


def _mermaid(root: str, edges: list[EdgeEntry], frames: list[str]) -> str:
    """`graph TD` of the frame tree. Node ids are f0 (the root), f1, ... in tree order; labels are the frame names."""
    ids: dict[str, str] = {}
    for frame in [root, *(f for e in edges for f in (e.parent, e.child)), *sorted(frames)]:
        ids.setdefault(frame, f"f{len(ids)}")
    lines = ["graph TD"]
    lines += [f'  {ident}["{_mermaid_label(frame)}"]' for frame, ident in ids.items()]
    lines += [f"  {ids[e.parent]} {ARROWS[e.origin.kind]} {ids[e.child]}" for e in edges]
    return "\n".join(lines)


def _output(plan: Plan, paths: _Paths) -> OutputEntry:
    dataset = plan.dataset
    segments = tuple(SegmentEntry(s.id, s.episode, s.stem, s.frames, paths(s.output)) for s in dataset.segments)
    return OutputEntry(
        layout=dataset.layout,
        application_id=plan.application_id,
        recording_id=plan.review_segment.output.recording_id,
        path=paths(plan.review_segment.output.path),
        segment_count=len(segments),
        segments=segments,
        model=paths(dataset.model) if dataset.model is not None else None,
        manifest=paths(dataset.manifest),
        joint_series=dataset.joint_series,
        trails=tuple(_trail(trail) for trail in plan.trails),
    )


def _trail(trail: TrailPlan) -> TrailEntry:
    window = "the whole recording" if trail.window is None else f"{number(trail.window)} {trail.window_unit}"
    return TrailEntry(trail.robot, trail.link, trail.frame, trail.style, window)


def _warnings(warnings: Sequence[ConfigWarning], paths: _Paths) -> tuple[WarningEntry, ...]:
    """Each warning once (a sidecar shared by two robots warns twice), by file, line, column, path, message."""
    items = {
        WarningEntry(
            file=paths.relative(w.where.file) if w.where is not None else None,
            line=w.where.line if w.where is not None else 0,
            column=w.where.column if w.where is not None and w.where.line else 0,
            path=w.where.path if w.where is not None else "",
            message=w.message,
        )
        for w in warnings
    }
    return tuple(sorted(items, key=lambda i: (i.file or "", i.line, i.column, i.path, i.message)))

"""The plan report as free-form text (`plan` without --format): each joint's conversion, edges and outputs, for a
terminal. Paths as the plan holds them; limits in source units, as markdown and json show them."""

from __future__ import annotations

from dataclasses import fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from ...errors import neutral_text, shown
from ..markdown_text import PATH_LIMIT
from .report_model import SERIES_TEXT, EdgeEntry, JointRow, OutputEntry, PlanReport, RobotEntry, SampleEntry, number


def _mapped_text(row: JointRow) -> str:
    steps = [f"wrap {row.wrap.period:g} around {row.wrap.center:g}"] if row.wrap else []
    if row.source_range is not None and row.target_range is not None:
        steps.append(f"source_range {list(row.source_range)} onto {[round(v, 9) for v in row.target_range]}")
    else:
        assert row.factor is not None and row.scale is not None and row.sign is not None and row.offset is not None
        scale = f" x {row.scale:g}" if row.scale != 1 else ""
        steps.append(f"x {row.factor:g} ({row.unit}){scale} x {row.sign:g} + {row.offset:g}")
    limits = row.limits_source_units
    if limits is None:
        steps.append("limits none")
    else:
        unit = row.limits_unit
        steps.append(f"limits {number(limits[0])} .. {number(limits[1])} {unit}, slack {row.slack_text}")
    return "; ".join(steps)


def _row_line(row: JointRow) -> str:
    if row.kind == "held":
        return f"    hold {row.joint} = {row.hold:g}"
    if row.kind == "mimic":
        assert row.mimic is not None
        return f"    mimic {row.joint} = {row.mimic.driver} * {row.mimic.multiplier:g} + {row.mimic.offset:g}"
    return f"    {row.source_name}[{row.source_index}] -> {row.joint}: {_mapped_text(row)}"


def _robot_lines(robot: RobotEntry) -> list[str]:
    lines = [
        f"robot {robot.key}: URDF '{robot.robot_name}' from {robot.urdf_path}",
        f"  entity {robot.entity_path_prefix}, frame prefix '{robot.frame_prefix}', root link {robot.root_frame}, "
        f"collisions {'kept' if robot.collision_geometries == 'keep' else 'dropped'}",
        *([f"  {robot.copy_text}"] if robot.copy_text else []),
    ]
    if robot.source is None:
        return [*lines, "  a scene: no moving joints, no joint source (static transforms only)"]
    lines += [
        f"  joints from source '{robot.source}', NaN policy {robot.nan_policy}; per value, in this order:",
        "    wrap (source units) -> (value * unit factor * scale) * sign + offset, or source_range onto the joint's range"
        " -> limits (clamp within slack) -> mimic joints",
    ]
    lines += [_row_line(row) for row in robot.joints]
    lines.append(f"  beyond-slack values: {robot.on_violation}")
    return lines


def _named(names: tuple[str, ...], indices: tuple[int, ...]) -> str:
    return "[" + ", ".join(f"{name}[{index}]" for name, index in zip(names, indices, strict=True)) + "]"


def _edge_lines(edge: EdgeEntry) -> list[str]:
    origin, temporal = edge.origin, edge.temporal
    if temporal is not None and temporal.tf_topic is not None:
        return [
            f"temporal edge {edge.parent} -> {edge.child} on {temporal.entity} ({origin.label}, line {origin.line}): "
            f"its transforms on {temporal.tf_topic} of source '{temporal.source}''s bag, on the source's timeline"
        ]
    if temporal is not None:
        return [
            f"temporal edge {edge.parent} -> {edge.child} on {temporal.entity} ({origin.label}, "
            f"line {origin.line}): per row of source '{temporal.source}', "
            f"translation {_named(temporal.translation_names, temporal.translation_indices)}, "
            f"quaternion_xyzw {_named(temporal.quaternion_names, temporal.quaternion_indices)} (normalised per row)"
        ]
    assert edge.translation is not None and edge.quaternion_xyzw is not None
    pose = f"t={[round(v, 9) for v in edge.translation]} q_xyzw={[round(v, 9) for v in edge.quaternion_xyzw]}"
    place = f" ({origin.label}, line {origin.line})" if origin.label else ""
    if origin.fixed_chain is not None:
        chain = origin.fixed_chain
        joints = ", ".join(chain.joints) or "none: from and to are the same link"
        return [
            f"edge {edge.parent} -> {edge.child}: fixed chain {chain.start} -> {chain.end} of robot {chain.robot}{place}",
            f"  fixed joints composed: {joints}; {pose}",
        ]
    if origin.kind == "assumed_identity":
        return [f"edge {edge.parent} -> {edge.child}: identity ASSUMED, not calibrated{place}"]
    return [f"edge {edge.parent} -> {edge.child}: {pose}{place}"]


def _output_lines(output: OutputEntry) -> list[str]:
    series = [f"  {SERIES_TEXT} (output.joint_series)"] if output.joint_series else []
    series += [f"  trail of {t.robot}'s {t.link} in {t.frame}: {t.style}, window {t.window} (trails)" for t in output.trails]
    if output.single:
        return [f"output {output.path.planned} (application_id {output.application_id}, recording_id {output.recording_id})", *series]
    segments = output.segments
    named = ", ".join(s.id for s in segments[:3]) + (f", ... {segments[-1].id}" if len(segments) > 3 else "")
    lines = [f"output: {len(segments)} segments ({named}), layout {output.layout}, application_id {output.application_id}"]
    if output.model is not None:
        lines.append(f"  model (meshes, static URDF transforms, written once, static only): {output.model.planned}")
    what = "layer (forward kinematics, calibration edges)" if output.layout == "split" else "recording"
    lines.append(f"  each segment's {what}: {segments[0].output.planned} ... recording_id = segment id")
    lines.append(f"  manifest: {output.manifest.planned}")
    return [*lines, *series]


def _sample_text(sample: SampleEntry) -> str:
    from ..check.check_joints import as_text  # check's own rendering of its verdicts (imports numpy: only with --sample)

    read = ", ".join(f"{name}: {rows}" for name, rows in sample.read.items())
    return f"sample (at most {sample.rows} rows of each source; read {read}):\n" + as_text(sample.reports)


# fields the text form does not print (all edges, the mermaid tree, warnings, a source's names: it counts them) or
# that check renders (the sample): left as they are
_KEPT = frozenset({"edges", "frame_tree", "warnings", "names", "sample"})


def _one_line(value: Any) -> Any:
    """The report with every name, path and value in it as errors.shown gives it (one line, control characters visible,
    shortened past PATH_LIMIT): what the text form prints from a config, URDF or file name cannot start a line of
    its own. Tool words and numbers are unchanged."""
    if isinstance(value, str):
        return shown(value, PATH_LIMIT)
    if isinstance(value, Path):
        return Path(shown(str(value), PATH_LIMIT))
    if isinstance(value, tuple):
        return tuple(_one_line(item) for item in value)
    if is_dataclass(value) and not isinstance(value, type):
        return replace(value, **{f.name: _one_line(getattr(value, f.name)) for f in fields(value) if f.init and f.name not in _KEPT})
    return value


def render_text(report: PlanReport) -> str:
    report = _one_line(report)
    lines = [f"config {report.config.planned}", f"root frame: {report.root_frame}"]
    lines += [f"source {source.name}: {source.kind} with {len(source.names)} names" for source in report.sources]
    for robot in report.robots:
        lines += _robot_lines(robot)
    for edge in report.configured_edges:
        lines += _edge_lines(edge)
    lines += _output_lines(report.output)
    lines += [f"picture {picture.label}: {picture.path}" for picture in report.pictures]
    text = "\n".join(lines)
    # the one guard for every name above: each line one line, control characters visible, bounded, no workflow command
    return neutral_text(text + ("\n" + _sample_text(report.sample) if report.sample is not None else "") + "\n")

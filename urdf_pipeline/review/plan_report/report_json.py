"""The plan report as JSON (`plan --format json`): the model as plain data, numbers rounded, keys sorted."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from ...plan import IndexPlan
from .report_model import REPORT_VERSION, EdgeEntry, JointRow, OutputEntry, PlanReport, RobotEntry, SourceEntry, rounded


def _rs(values: Sequence[float] | None) -> list[float] | None:
    return None if values is None else [rounded(v) for v in values]


def _r(value: float | None) -> float | None:
    return None if value is None else rounded(value)


def _source(source: SourceEntry) -> dict[str, Any]:
    result: dict[str, Any] = {"kind": source.kind, "name": source.name, source.file_key: source.file.relative, "names": list(source.names)}
    for key, value in source.settings:
        result[key] = {"column": value.column, "kind": value.kind, "unit": value.unit} if isinstance(value, IndexPlan) else value
    return result


def _row(row: JointRow) -> dict[str, Any]:
    observed = row.observed
    return {
        "kind": row.kind,
        "source_name": row.source_name,
        "source_index": row.source_index,
        "joint": row.joint,
        "type": row.type,
        "unit": row.unit,
        "sign": _r(row.sign),
        "offset": _r(row.offset),
        "scale": _r(row.scale),
        "wrap": {"period": rounded(row.wrap.period), "center": rounded(row.wrap.center)} if row.wrap else None,
        "source_range": _rs(row.source_range),
        "target_range": _rs(row.target_range),
        "limits_source_units": _rs(row.limits_source_units),
        "slack_source_units": _r(row.slack_source_units),
        "slack": {"value": rounded(row.slack[0]), "unit": row.slack[1]} if row.slack else None,
        "limits_urdf": _rs(row.limits_urdf),
        "mimic": {"driver": row.mimic.driver, "multiplier": rounded(row.mimic.multiplier), "offset": rounded(row.mimic.offset)}
        if row.mimic
        else None,
        "hold": _r(row.hold),
        "observed": None
        if observed is None
        else {
            "rows": observed.rows,
            "min": _r(observed.min),
            "max": _r(observed.max),
            "fits": observed.fits,
            "verdict": observed.verdict,
            "slack_rows": observed.slack_rows,
        },
    }


def _robot(robot: RobotEntry) -> dict[str, Any]:
    return {
        "key": robot.key,
        "robot_name": robot.robot_name,
        "urdf": {"origin": robot.urdf_origin, "sha256": robot.urdf_sha256},
        "entity_path_prefix": robot.entity_path_prefix,
        "frame_prefix": robot.frame_prefix,
        "root_frame": robot.root_frame,
        "collision_geometries": robot.collision_geometries,
        "source": robot.source,
        "nan_policy": robot.nan_policy,
        "on_violation": robot.on_violation,
        "joint_counts": dict(robot.joint_counts),
        "joints": [_row(row) for row in robot.joints],
        "ignored_source_values": list(robot.ignored_source_values),
        **({"appearance": {"color": list(robot.appearance[:3]), "opacity": robot.appearance[3]}} if robot.appearance else {}),
        **({"compare": {"robot": robot.compare[0], "threshold": robot.compare[1]}} if robot.compare else {}),
    }


def _edge(edge: EdgeEntry) -> dict[str, Any]:
    o, temporal = edge.origin, edge.temporal
    return {
        "parent": edge.parent,
        "child": edge.child,
        "translation_m": _rs(edge.translation),
        "rotation_rpy_deg": None if edge.rotation_rpy_deg is None else list(edge.rotation_rpy_deg),
        "temporal": None
        if temporal is None
        else {
            "source": temporal.source,
            "entity": temporal.entity,
            "translation_names": list(temporal.translation_names),
            "translation_indices": list(temporal.translation_indices),
            "quaternion_xyzw_names": list(temporal.quaternion_names),
            "quaternion_xyzw_indices": list(temporal.quaternion_indices),
            "tf_topic": temporal.tf_topic,
        },
        "origin": {
            "kind": o.kind,
            "description": o.description,
            "robot": o.robot,
            "joint": o.joint,
            "joint_type": o.joint_type,
            "file": o.file,
            "line": o.line,
            "label": o.label,
            "source": o.source,
            "fixed_chain": list(o.fixed_chain.joints) if o.fixed_chain is not None else None,
        },
    }


def _output(output: OutputEntry) -> dict[str, Any]:
    return {
        "layout": output.layout,
        "application_id": output.application_id,
        "segment_count": output.segment_count,
        "segments": [
            {"id": s.id, "episode": s.episode, "stem": s.stem, "frames": s.frames, "output": s.output.relative} for s in output.segments
        ],
        "model": output.model.relative if output.model is not None else None,
        "manifest": output.manifest.relative,
        **({"joint_series": True} if output.joint_series else {}),  # only when set: the golden reports stay as they are
        **(
            {"trails": [{"robot": t.robot, "link": t.link, "frame": t.frame, "style": t.style, "window": t.window} for t in output.trails]}
            if output.trails
            else {}
        ),
    }


def report_data(report: PlanReport) -> dict[str, Any]:
    """The report as plain data: no absolute path, no time."""
    sample = report.sample
    pictures = {"pictures": [{"label": p.label, "path": p.path} for p in report.pictures]} if report.pictures else {}
    return {
        "report_version": REPORT_VERSION,
        "config": report.config.relative,
        "root_frame": report.root_frame,
        "sources": [_source(source) for source in report.sources_by_name],
        "robots": [_robot(robot) for robot in report.robots],
        "edges": [_edge(edge) for edge in report.edges],
        "frame_tree": {"root": report.root_frame, "mermaid": report.mermaid},
        "output": _output(report.output),
        "warnings": [{"file": w.file, "line": w.line, "column": w.column, "path": w.path, "message": w.message} for w in report.warnings],
        "sample": None if sample is None else {"rows": sample.rows, "read": dict(sample.read)},
        **pictures,  # with --render only: the golden reports stay as they are
    }


def render_json(report: PlanReport) -> str:
    return json.dumps(report_data(report), indent=2, sort_keys=True) + "\n"

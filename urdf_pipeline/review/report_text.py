"""The plan as free-form text (`plan` without --format): each joint's conversion, edges and outputs, for a terminal."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..plan import JointChannel, Plan, RobotPlan

if TYPE_CHECKING:
    pass


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

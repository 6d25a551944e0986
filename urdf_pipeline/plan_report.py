"""A human-readable account of a plan, for `urdf-pipeline plan` and PR review."""

from __future__ import annotations

from .plan import Plan, RobotPlan


def _robot_lines(robot: RobotPlan) -> list[str]:
    lines = [
        f"robot {robot.key}: URDF '{robot.robot_name}' from {robot.urdf_path}",
        f"  entity {robot.entity_path_prefix}, frame prefix '{robot.frame_prefix}', root link {robot.frame_prefix}{robot.root_link}, collisions {'kept' if robot.keep_collisions else 'dropped'}",
        f"  joints from source '{robot.source}' (urdf = (value * unit factor) * sign + offset; then limits; then mimic):",
    ]
    for c in robot.channels:
        limits = f"[{c.lower:g}, {c.upper:g}]" if c.lower is not None else "none"
        lines.append(
            f"    {c.source_name}[{c.source_index}] -> {c.joint}: x {c.factor:g} ({c.source_unit}) x {c.sign:g} + {c.offset:g}; limits {limits}, slack {c.slack:g}"
        )
    lines += [f"    hold {h.joint} = {h.value:g}" for h in robot.holds]
    lines += [f"    mimic {m.joint} = {m.driver} * {m.multiplier:g} + {m.offset:g}" for m in robot.mimics]
    lines.append(f"  beyond-slack values: {robot.on_violation}")
    return lines


def describe_plan(plan: Plan) -> str:
    lines = [f"config {plan.config_path}", f"root frame: {plan.root_frame}"]
    for source in plan.sources:
        lines.append(f"source {source.name}: {type(source).__name__.removesuffix('SourcePlan').lower()} with {len(source.names)} names")
    for robot in plan.robots:
        lines += _robot_lines(robot)
    for edge in plan.edges:
        lines.append(f"edge {edge.parent} -> {edge.child}: t={list(edge.translation)} q_xyzw={[round(v, 9) for v in edge.quaternion_xyzw]}")
    lines.append(f"output {plan.output.path} (application_id {plan.output.application_id}, recording_id {plan.output.recording_id})")
    return "\n".join(lines)

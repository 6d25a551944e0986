"""After the data pass: one line per joint about limits and bad values; errors stop the run before writing."""

from __future__ import annotations

from ..compile import unit_hint
from ..errors import Problems
from ..plan import JointChannel
from ..sources import JointValueMapper


def _limits_text(channel: JointChannel) -> str:
    """The limits as plan and check print them (JointChannel.limits_in_source_unit)."""
    limits = channel.limits_in_source_unit
    if limits is None:
        return "none"
    return f"[{limits[0]:.6g}, {limits[1]:.6g}] {channel.source_unit}"


def check_joint_statistics(mapper: JointValueMapper, problems: Problems) -> list[str]:
    """Return notes for the user; add errors for values that must stop the run."""
    robot = mapper.robot
    notes: list[str] = []
    if mapper.stats.rows == 0:
        problems.add(f"source '{mapper.source.name}' yielded zero rows for robot '{robot.key}'; nothing would move", mapper.source.where)
        return notes
    if mapper.stats.dropped_rows:
        notes.append(
            f"robot '{robot.key}': left out {mapper.stats.dropped_rows} of {mapper.stats.rows} rows with NaN or infinite values (joints.nan: {robot.nan_policy})"
        )
    if mapper.stats.filled_rows:
        notes.append(
            f"robot '{robot.key}': filled {mapper.stats.filled_rows} of {mapper.stats.rows} rows with the last valid values (joints.nan: hold_last)"
        )
    for channel, stats in zip(robot.channels, mapper.stats.channels, strict=False):
        label = f"robot '{robot.key}' joint '{channel.joint}' (source value '{channel.source_name}')"
        if stats.nonfinite_rows:
            problems.add(
                f"{label}: {stats.nonfinite_rows} of {mapper.stats.rows} rows are NaN or infinite, the first at row {stats.first_nonfinite_row} "
                "of the source; set joints.nan: drop_row or hold_last to accept them",
                channel.where,
            )
        if stats.clamped_rows:
            notes.append(
                f"{label}: clamped {stats.clamped_rows} of {mapper.stats.rows} rows within slack {channel.slack_text} "
                f"of limits {_limits_text(channel)}; worst value {stats.clamped_worst_raw:.6g} {channel.source_unit}"
            )
        if stats.beyond_rows:
            text = (
                f"{label}: {stats.beyond_rows} of {mapper.stats.rows} rows beyond the URDF limits {_limits_text(channel)} "
                f"by more than slack {channel.slack_text}; worst value {stats.beyond_worst_raw:.6g} {channel.source_unit}"
            )
            hint = unit_hint(channel, stats.raw_min, stats.raw_max) if stats.raw_min <= stats.raw_max else ""
            if robot.on_violation == "error" and hint:
                problems.add(f"{text}; {hint} on this entry (or joints.unit for the whole robot)", channel.where)
            elif robot.on_violation == "error":
                problems.add(
                    f"{text}. Check this entry's joint, unit, sign and offset, or set joints.limits.on_violation: clamp", channel.where
                )
            elif robot.on_violation == "clamp":
                notes.append(f"{text}; clamped (on_violation: clamp)")
            else:
                notes.append(f"{text}; passed through (on_violation: ignore)")
    return notes

"""`urdf-pipeline check`: which corrections put a sample of each mapped joint's values inside its URDF limits.

For revolute joints the candidates are identity, negate, wrap by a full turn, offsets of +-90 and +-180 degrees,
and their combinations; for prismatic joints the unit factors m, cm, mm and negation. Candidates that give the
same values on the sample are one candidate (the simplest is shown). One fitting candidate: the YAML to paste;
several: ambiguous, settle against a known pose; none: the column is probably another joint or the order is off.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..compile import compile_config
from ..errors import ExitCode
from ..plan import JointChannel, Plan, RobotPlan, SourcePlan
from ..sources import wrapped

SAMPLE_ROWS = 100_000


@dataclass(frozen=True)
class Candidate:
    sign: int
    wrap: bool
    offset_deg: float  # revolute: added after conversion, in degrees (pasted as radians)
    unit_factor: float  # prismatic: metres per source unit

    def describe(self, channel: JointChannel) -> str:
        parts = []
        if channel.lower is not None and self.unit_factor != channel.factor * channel.scale and not _angular(channel):
            parts.append(f"x {self.unit_factor:g} m per source unit")
        if self.sign < 0:
            parts.append("negate")
        if self.wrap:
            parts.append("wrap a full turn")
        if self.offset_deg:
            parts.append(f"offset {self.offset_deg:+g} deg")
        return ", ".join(parts) or "identity"

    def yaml(self, channel: JointChannel) -> str:
        entry = [f"joint: {channel.joint}"]
        if _angular(channel):
            entry.append(f"unit: {channel.source_unit}")
            if channel.scale != 1:
                entry.append(f"scale: {channel.scale:g}")
            if self.wrap:
                entry.append(f"wrap: {360 if channel.source_unit == 'deg' else round(2 * math.pi, 9)}")
        else:
            unit, scale = _linear_unit(self.unit_factor)
            entry.append(f"unit: {unit}")
            if scale != 1:
                entry.append(f"scale: {scale:g}")
        if self.sign < 0:
            entry.append("sign: -1")
        if self.offset_deg:
            entry.append(f"offset: {round(math.radians(self.offset_deg), 9)}")
        return f"{channel.source_name}: {{{', '.join(entry)}}}"


@dataclass(frozen=True)
class JointReport:
    """check's verdict on one mapped value: the model `check`'s text and json (and `plan --sample`) render."""

    robot: str
    source_name: str
    joint: str
    source_unit: str
    rows: int
    raw_min: float | None
    raw_max: float | None
    limits_in_source_unit: tuple[float, float] | None  # JointChannel.limits_in_source_unit: the config's corrections
    verdict: str  # "fits" | "ambiguous" | "none" | "no limits" | "no values"
    current_fits: bool
    fitting: tuple[str, ...] = ()
    paste: str | None = None
    slack_rows: int = 0
    slack_worst: float | None = None
    message: str = ""


def _angular(channel: JointChannel) -> bool:
    return channel.source_unit in ("rad", "deg")


def _linear_unit(factor: float) -> tuple[str, float]:
    if math.isclose(factor, 1.0):
        return "m", 1.0
    if math.isclose(factor, 1e-2):
        return "cm", 1.0
    if math.isclose(factor, 1e-3):
        return "mm", 1.0
    return "m", factor


def _candidates(channel: JointChannel) -> list[Candidate]:
    if _angular(channel):
        base = channel.factor * channel.scale
        offsets = (0.0, 90.0, -90.0, 180.0, -180.0)
        combos = itertools.product(offsets, (1, -1), (False, True))
        ordered = sorted(combos, key=lambda c: (c[0] != 0, abs(c[0]), c[0] < 0, c[2], c[1] < 0))
        return [Candidate(sign, wrap, offset, base) for offset, sign, wrap in ordered]
    return [Candidate(sign, False, 0.0, factor) for factor in (1.0, 1e-2, 1e-3) for sign in (1, -1)]


def _values(channel: JointChannel, raw: np.ndarray, candidate: Candidate) -> np.ndarray:
    turn = 360.0 if channel.source_unit == "deg" else 2 * math.pi
    if candidate.wrap:
        center = channel.to_source_unit(((channel.lower or 0.0) + (channel.upper or 0.0)) / 2)
        raw = wrapped(raw, center, turn)
    return raw * candidate.unit_factor * candidate.sign + math.radians(candidate.offset_deg) * (1 if _angular(channel) else 0)


def _is_current(candidate: Candidate, channel: JointChannel) -> bool:
    if channel.source_range is not None:
        return False
    return (
        candidate.sign == channel.sign
        and math.isclose(math.radians(candidate.offset_deg) if _angular(channel) else 0.0, channel.offset, abs_tol=1e-9)
        and candidate.wrap == bool(channel.wrap)
        and math.isclose(candidate.unit_factor, channel.factor * channel.scale)
    )


def _current_values(channel: JointChannel, raw: np.ndarray) -> np.ndarray:
    if channel.wrap:
        raw = wrapped(raw, channel.wrap_center, channel.wrap)
    return raw * channel.gain + channel.bias


def check_channel(robot: RobotPlan, channel: JointChannel, raw: np.ndarray) -> JointReport:
    finite = raw[np.isfinite(raw)]
    report = JointReport(
        robot.key, channel.source_name, channel.joint, channel.source_unit, len(raw),
        float(finite.min()) if finite.size else None, float(finite.max()) if finite.size else None,
        None, "no values", False,
    )  # fmt: skip
    if not finite.size:
        return replace(report, message="no finite values in the sample")
    if channel.lower is None or channel.upper is None:
        return replace(report, verdict="no limits", current_fits=True, message="the joint has no limits: nothing to check against")
    lower, upper, slack = channel.lower, channel.upper, channel.slack
    current = _current_values(channel, finite)
    fits = bool(np.all((current >= lower - slack) & (current <= upper + slack)))
    report = replace(report, limits_in_source_unit=channel.limits_in_source_unit, current_fits=fits)
    outside = (current < lower) | (current > upper)
    if fits and outside.any():
        excess = np.maximum(lower - current, current - upper)
        report = replace(report, slack_rows=int(outside.sum()), slack_worst=float(finite[np.argmax(excess)]))
    if channel.source_range is not None:  # the config maps the range itself: only the fit is to check
        if fits:
            return replace(report, verdict="fits", message="source_range maps the values onto the joint's range")
        message = f"values leave source_range {list(channel.source_range)}: the range (or the column) is wrong"
        return replace(report, verdict="none", message=message)
    kept: list[tuple[Candidate, np.ndarray]] = []
    for candidate in _candidates(channel):
        values = _values(channel, finite, candidate)
        if not np.all((values >= lower - slack) & (values <= upper + slack)):
            continue
        if any(np.allclose(values, other, atol=1e-9) for _, other in kept):
            continue
        kept.append((candidate, values))
    report = replace(report, fitting=tuple(c.describe(channel) + (" (the config's)" if _is_current(c, channel) else "") for c, _ in kept))
    if len(kept) == 1:
        return replace(report, verdict="fits", paste=kept[0][0].yaml(channel), message="one correction fits")
    if kept:
        return replace(report, verdict="ambiguous", message="several corrections fit: settle against a known pose")
    message = "no correction fits: the column is probably another joint, or the name order is off"
    return replace(report, verdict="none", message=message)


def check_plan(plan: Plan, sample: dict[str, np.ndarray]) -> list[JointReport]:
    """`sample`: source name -> (rows x names) raw values."""
    reports = []
    for robot in plan.robots:
        if robot.source is None:
            continue
        raw = sample[robot.source]
        reports += [check_channel(robot, channel, raw[:, channel.source_index]) for channel in robot.channels]
    return reports


def read_sample(source: SourcePlan, rows: int = SAMPLE_ROWS) -> np.ndarray:
    """The first `rows` rows of a source, as a (rows x names) matrix, read with the same Rerun reader as a run."""
    from ..sources import module_for, raw_matrix, sorted_in_memory

    with sorted_in_memory():  # the first rows in time order, every repeat seen: as a run reads the source
        opened = module_for(source).open_stream(source)
    matrices, total = [], 0
    for chunk in opened.stream.to_chunks():
        batch = chunk.to_record_batch()
        if opened.component not in batch.schema.names:
            continue
        column = batch.column(opened.component).flatten()
        matrices.append(raw_matrix(source, column))
        total += len(column)
        if total >= rows:
            break
    width = len(source.names)
    return np.concatenate(matrices)[:rows] if matrices else np.empty((0, width))


def check_exit_code(reports: Sequence[JointReport]) -> int:
    return ExitCode.OK if all(r.current_fits for r in reports) else ExitCode.DOES_NOT_FIT


def check_config(config: Path, rows: int = SAMPLE_ROWS) -> list[JointReport]:
    """`check CONFIG`: the first `rows` rows of every source that drives a robot, checked joint by joint."""
    plan = compile_config(config)
    sample = {source.name: read_sample(source, rows) for source in plan.sources if plan.robots_for(source.name)}
    return check_plan(plan, sample)


def render_check(reports: Sequence[JointReport], format: str) -> str:
    """`check`'s output: the reports as text, or as one JSON list."""
    if format == "json":
        import json

        return json.dumps([asdict(r) for r in reports], indent=2) + "\n"
    return as_text(reports) + "\n"


def as_text(reports: Sequence[JointReport]) -> str:
    lines: list[str] = []
    robot = None
    for r in reports:
        if r.robot != robot:
            robot = r.robot
            lines.append(f"robot {robot}: {r.rows} sampled rows")
        status = "ok" if r.current_fits else "DOES NOT FIT"
        limits = f"{r.limits_in_source_unit[0]:.6g} .. {r.limits_in_source_unit[1]:.6g}" if r.limits_in_source_unit else "none"
        raw = f"{r.raw_min:.6g} .. {r.raw_max:.6g}" if r.raw_min is not None else "no values"
        lines.append(
            f"  {r.source_name} -> {r.joint} [{r.source_unit}]: values {raw}; URDF limits {limits}; with the config's corrections: {status}"
        )
        if r.slack_rows:
            lines.append(
                f"    calibration slack: {r.slack_rows} rows just outside the limits (worst {r.slack_worst:.6g}), within the slack"
            )
        if r.fitting:
            lines.append(f"    fitting corrections: {'; '.join(r.fitting)}")
        lines.append(f"    {r.verdict}: {r.message}")
        if r.paste:
            lines.append(f"    paste: {r.paste}")
    return "\n".join(lines)

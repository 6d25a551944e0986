"""`urdf-pipeline check`: which corrections put a sample of each mapped joint's values inside its URDF limits, from
check_candidates.py's candidates; its verdicts and advice: docs/commands.md#check."""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ...compile import ANGULAR_UNITS, UNIT_NAMES, bigger_unit, compile_config, unit_fits, within
from ...errors import ExitCode, UserError, Where, listing, quoted, shown
from ...plan import JointChannel, LeRobotSourcePlan, Plan, RobotPlan, Segment, SourcePlan
from ...sources import wrapped
from .check_candidates import angular, fitting

SAMPLE_ROWS = 100_000
EPISODE_OPTION = Where(Path("--episode"), 0)  # `check --episode`, where its errors point


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
    unit_fits: str | None = None  # the simplest advice changes the unit only, to this one
    bigger_unit: str | None = None  # fits as configured, but its values look like this bigger unit (deg -> rad)
    robot_advice: str | None = None  # every joint of this kind fits in another unit: the robot's joints.unit to paste
    segments: tuple[str, ...] = ()  # the ids of the segments whose first rows were sampled (`check` sets them)

    def limits_text(self) -> str:
        """`-166 .. 166`, the limits in source units as check and init show them, or `none`."""
        limits = self.limits_in_source_unit
        return f"{limits[0]:.6g} .. {limits[1]:.6g}" if limits else "none"

    def values_text(self) -> str:
        """`-12.5 .. 171`, the sampled raw range, or `no values`."""
        return f"{self.raw_min:.6g} .. {self.raw_max:.6g}" if self.raw_min is not None and self.raw_max is not None else "no values"


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
    lower, upper = channel.lower, channel.upper
    current = _current_values(channel, finite)
    current_fits = within(channel, current)
    report = replace(report, limits_in_source_unit=channel.limits_in_source_unit, current_fits=current_fits)
    outside = (current < lower) | (current > upper)
    if current_fits and outside.any():
        excess = np.maximum(lower - current, current - upper)
        report = replace(report, slack_rows=int(outside.sum()), slack_worst=float(finite[np.argmax(excess)]))
    if channel.source_range is not None:  # the config maps the range itself: only the fit is to check
        if current_fits:
            return replace(report, verdict="fits", message="source_range maps the values onto the joint's range")
        message = f"values leave source_range {list(channel.source_range)}: the range (or the column) is wrong"
        return replace(report, verdict="none", message=message)
    kept = fitting(channel, finite)
    report = replace(report, fitting=tuple(c.describe(channel) + (" (the config's)" if c.is_current(channel) else "") for c in kept))
    if current_fits:
        bigger = bigger_unit(channel, finite)
        if bigger is None:
            return replace(report, verdict="fits", message="fits as configured")
        reach = float(np.max(np.abs(finite)))
        message = (
            f"fits as configured, but the values also fit if they are {UNIT_NAMES[bigger]} (`unit: {bigger}`): as "
            f"{channel.source_unit} they all stay within {reach:.3g} {channel.source_unit} of zero on a joint whose limits span "
            f"{(upper - lower) / abs(channel.gain):.4g} {channel.source_unit}; settle against a known pose"
        )
        return replace(report, verdict="ambiguous", message=message, bigger_unit=bigger)
    if not kept:
        message = "no correction fits: the column is probably another joint, or the name order is off"
        return replace(report, verdict="none", message=message)
    simplest = [c for c in kept if len(c.changes(channel)) == len(kept[0].changes(channel))]
    more = len(kept) - len(simplest)
    also = f" ({more} more with more changes fit too: {'; '.join(c.describe(channel) for c in kept[len(simplest) :][:3])})" if more else ""
    if len(simplest) == 1:
        best = simplest[0]
        unit = best.unit if best.changes(channel) == ("unit",) else None
        return replace(report, verdict="fits", paste=best.yaml(channel), message=best.advice(channel) + also, unit_fits=unit)
    count = len(simplest[0].changes(channel))
    units = {c.unit for c in simplest}
    if len(units) == 1 and channel.source_unit not in units:  # every way out changes the unit: that much is sure
        (unit,) = units
        rest = "; ".join(replace(c, unit=channel.source_unit).describe(channel) for c in simplest)
        message = f"the values fit only if they are {UNIT_NAMES[unit]} (`unit: {unit}`), and then one of: {rest}"
    else:
        listed = "; ".join(c.describe(channel) for c in simplest)
        message = f"several corrections fit with {count} change{'s' if count > 1 else ''} each: {listed}"
    return replace(report, verdict="ambiguous", message=message + "; settle against a known pose")


def _robot_advice(robot: RobotPlan, reports: list[JointReport], raw: np.ndarray) -> list[JointReport]:
    """When some joint's advice is another unit and every mapped joint of that kind fits in it (with its own sign,
    offset and wrap), the robot's `joints.unit` is the one line to change: say it on each of the robot's reports.
    Likewise when the values fit as configured but some joint's look like a bigger unit (radians configured as `deg`)
    and every joint of that kind fits in it too: a robot near its rest pose leaves most joints near zero in either
    unit, so one joint's doubt is the robot's."""
    by_channel = {(r.source_name, r.joint): r for r in reports}
    advised = {r.unit_fits for r in reports if r.unit_fits is not None}
    suspected = {r.bigger_unit for r in reports if r.bigger_unit is not None} - advised
    for unit in sorted(advised | suspected):
        kind = [c for c in robot.channels if c.source_range is None and angular(c) == (unit in ANGULAR_UNITS)]
        agree = all(
            np.isfinite(raw[:, c.source_index]).any() and unit_fits(c, unit, _finite(raw[:, c.source_index]))
            for c in kind
            if c.lower is not None and c.upper is not None
        )
        if not agree:
            continue
        what = "revolute and continuous" if unit in ANGULAR_UNITS else "prismatic"
        written = f"write `unit: {_robot_unit(robot, unit)}` under robots.{robot.key}.joints"
        if unit in advised:
            advice = f"every {what} joint of robot {robot.key} fits if its values are {UNIT_NAMES[unit]}: {written}"
        else:
            looking = sum(1 for r in reports if r.bigger_unit == unit)
            advice = (
                f"every {what} joint of robot {robot.key} fits as configured and also if its values are {UNIT_NAMES[unit]}, "
                f"and {looking} of them look like {UNIT_NAMES[unit]} (as configured they barely leave zero): if they are, "
                f"{written}; settle against a known pose"
            )
        for c in kind:
            report = by_channel.get((c.source_name, c.joint))
            if report is not None and report.robot_advice is None:
                by_channel[(c.source_name, c.joint)] = replace(report, robot_advice=advice)
    return [by_channel[(r.source_name, r.joint)] for r in reports]


def _robot_unit(robot: RobotPlan, unit: str) -> str:
    """The robot's `joints.unit` with `unit` for its kind, the other kind's unit kept (`{angle: deg, length: mm}`)."""
    others = {c.source_unit for c in robot.channels if c.source_range is None and angular(c) != (unit in ANGULAR_UNITS)}
    other = next(iter(others)) if len(others) == 1 else None
    if unit in ANGULAR_UNITS:
        return f"{{angle: {unit}, length: {other}}}" if other not in (None, "m") else unit
    return f"{{angle: {other}, length: {unit}}}" if other not in (None, "rad") else unit


def _finite(column: np.ndarray) -> np.ndarray:
    return column[np.isfinite(column)]


def check_plan(plan: Plan, sample: dict[str, np.ndarray]) -> list[JointReport]:
    """`sample`: source name -> (rows x names) raw values."""
    reports = []
    for robot in plan.robots:
        if robot.source is None:
            continue
        raw = sample[robot.source]
        robot_reports = [check_channel(robot, channel, raw[:, channel.source_index]) for channel in robot.channels]
        reports += _robot_advice(robot, robot_reports, raw)
    return reports


def plan_sample(plan: Plan, rows: int = SAMPLE_ROWS) -> dict[str, np.ndarray]:
    """`read_sample` of every source that drives a robot, in the segment review shows (`Plan.review_segment`, the
    first): the sample `plan --sample` and `init` judge, and `check` without --episode or --spread."""
    return segments_sample(plan, plan.segments[:1], rows)


def segments_sample(plan: Plan, segments: Sequence[Segment], rows: int = SAMPLE_ROWS) -> dict[str, np.ndarray]:
    """The first `rows` rows of every robot-driving source of each segment, concatenated per source in segment order:
    one segment's values judged against the limits as several segments' are."""
    read: dict[str, list[np.ndarray]] = {}
    for segment in segments:
        for source in segment.sources:
            if plan.robots_for(source.name):
                read.setdefault(source.name, []).append(read_sample(source, rows))
    return {name: np.concatenate(matrices) for name, matrices in read.items()}


def spread_segments(segments: Sequence[Segment], count: int) -> tuple[Segment, ...]:
    """`count` segments spread evenly over `segments`: the first, the last and evenly between (all when fewer)."""
    if count >= len(segments):
        return tuple(segments)
    if count == 1:
        return (segments[0],)
    picked = dict.fromkeys(round(i * (len(segments) - 1) / (count - 1)) for i in range(count))
    return tuple(segments[i] for i in picked)


def sampled_segments(plan: Plan, episode: str | None, spread: int | None) -> tuple[Segment, ...]:
    """The segments `check` samples: `spread` of them spread over the (selected) segments, else the one `--episode`
    selects (an error when it selects several), else the first."""
    if spread is not None:
        return spread_segments(plan.segments, spread)
    if episode is not None and len(plan.segments) > 1:
        ids = [segment.id for segment in plan.segments]
        message = f"{quoted(episode)} selects {len(ids)} segments ({listing(ids)}): name one episode, or add --spread N to sample several"
        raise UserError(message, EPISODE_OPTION)
    return plan.segments[:1]


def read_sample(source: SourcePlan, rows: int = SAMPLE_ROWS) -> np.ndarray:
    """The first `rows` rows of a source, as a (rows x names) matrix, read with the same Rerun reader as a run (a
    remote LeRobot dataset's episode from a local view of its files, as a run reads it)."""
    from ...sources import local_dataset, module_for, raw_matrix, sorted_in_memory

    matrices, total = [], 0
    with ExitStack() as held:
        if isinstance(source, LeRobotSourcePlan):
            source = held.enter_context(local_dataset(source))
        with sorted_in_memory():  # the first rows in time order, every repeat seen: as a run reads the source
            opened = module_for(source).open_stream(source)
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


def check_config(config: Path, rows: int = SAMPLE_ROWS, episode: str | None = None, spread: int | None = None) -> list[JointReport]:
    """`check CONFIG`: the first `rows` rows of every source that drives a robot, checked joint by joint, in the first
    segment, the one `episode` selects (run's --episodes syntax and errors), or `spread` segments over the dataset;
    each report names the segments sampled."""
    plan = compile_config(config, episode, EPISODE_OPTION.file.as_posix())
    segments = sampled_segments(plan, episode, spread)
    ids = tuple(segment.id for segment in segments)
    return [replace(report, segments=ids) for report in check_plan(plan, segments_sample(plan, segments, rows))]


def render_check(reports: Sequence[JointReport], format: str) -> str:
    """`check`'s output: the reports as text, or as one JSON list."""
    if format == "json":
        import json

        return json.dumps([asdict(r) for r in reports], indent=2) + "\n"
    ids = dict.fromkeys(i for r in reports for i in r.segments)
    sampled = f"sampled segment{'s' if len(ids) > 1 else ''}: {listing(list(ids), limit=100)}\n" if ids else ""
    return sampled + as_text(reports) + "\n"


def as_text(reports: Sequence[JointReport]) -> str:
    lines: list[str] = []
    robot = None
    for i, r in enumerate(reports):
        if r.robot != robot:
            robot = r.robot
            lines.append(f"robot {shown(robot)}: {r.rows} sampled rows")
        status = "ok" if r.current_fits else "DOES NOT FIT"
        lines.append(
            f"  {shown(r.source_name)} -> {shown(r.joint)} [{r.source_unit}]: values {r.values_text()}; URDF limits {r.limits_text()}; "
            f"with the config's corrections: {status}"
        )
        if r.slack_rows:
            lines.append(
                f"    calibration slack: {r.slack_rows} rows just outside the limits (worst {r.slack_worst:.6g}), within the slack"
            )
        if r.fitting:
            lines.append(f"    fitting corrections: {'; '.join(r.fitting)}")
        lines.append(f"    {r.verdict}: {shown(r.message, 1000)}")
        if r.paste:
            lines.append(f"    paste: {shown(r.paste, 1000)}")
        if i + 1 == len(reports) or reports[i + 1].robot != r.robot:  # the robot's last joint: its whole-robot advice, once
            advice = dict.fromkeys(x.robot_advice for x in reports if x.robot == r.robot and x.robot_advice)
            lines += [f"  whole robot: {a}" for a in advice if a]
    return "\n".join(lines)

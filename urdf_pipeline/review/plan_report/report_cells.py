"""The sections Markdown and HTML share (summary, sources, robots, joint and edge tables, output, warnings): what a line or
a cell says is decided once, here; each renderer gives its own markup (`Markup`) for names, free text, verdicts and
counts."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from ...plan import IndexPlan
from .report_model import (
    JOINT_TYPES,
    SERIES_TEXT,
    EdgeEntry,
    JointRow,
    Observed,
    OutputEntry,
    PlanReport,
    RobotEntry,
    SampleEntry,
    SegmentEntry,
    SettingValue,
    SourceEntry,
    number,
    rounded,
)

DASH = "—"
EDGES_NOTE = (
    "Every edge of the frame graph, top down from the root. URDF moving joints are shown at their origin (joint value 0); "
    "the run logs their pose per row."
)
SOURCE_HEADER = ["source", "kind", "file", "reads", "values"]
JOINT_HEADER = ["source name", "URDF joint", "type", "unit", "sign", "offset (URDF units)", "scale / range map"]
JOINT_HEADER += ["limits (source units)", "mimic driver / hold"]
EDGE_HEADER = ["parent", "child", "translation (m)", "rotation (rpy deg)", "origin"]
ORDER_NOTE = (  # each renderer ends the sentence
    "Per source value, in this order: wrap (source units) → value × unit factor × scale × sign + offset (offset in URDF "
    "units), or source_range mapped onto the joint's range → limits (clamped within the slack) → mimic joints. Limits in "
    "source units are the raw values these corrections send onto the URDF limits, low to high"
)


@dataclass(frozen=True)
class Markup:
    """How one renderer marks up the parts of a cell."""

    code: Callable[[object], str]  # a name from input (a joint), inert in this format
    path: Callable[[object], str]  # a path from input, as this format shows one
    text: Callable[[object], str]  # free text from input (the slack as written)
    literal: Callable[[str], str]  # an expression of ours shown as code (`hold = 0.5`)
    bad: Callable[[str], str]  # a verdict to see first
    good: Callable[[str], str]
    count: Callable[[int], str]
    setting: Callable[[object], str]  # a source setting's value from input (a dataset, a column, a topic)
    names_shown: int  # names in one list (ignored source values): one line stays readable however many there are

    def names(self, names: Sequence[str]) -> str:
        """Code spans, the first `names_shown` of them."""
        more = f" and {len(names) - self.names_shown:,} more" if len(names) > self.names_shown else ""
        return ", ".join(self.code(name) for name in names[: self.names_shown]) + more


def plural(count: int, word: str, markup: Markup) -> str:
    return f"{markup.count(count)} {word}{'' if count == 1 else 's'}"


def summary(report: PlanReport, markup: Markup) -> str:
    """Root frame, robots, sources, edges and segments, counted."""
    edges = report.edges
    configured = sum(1 for e in edges if not e.origin.kind.startswith("urdf_"))
    return (
        f"Root frame {markup.code(report.root_frame)}; {plural(len(report.robots), 'robot', markup)}, "
        f"{plural(len(report.sources), 'source', markup)}, {plural(len(edges), 'edge', markup)} ({markup.count(configured)} from "
        f"the config, {markup.count(len(edges) - configured)} URDF joints), {plural(report.output.segment_count, 'segment', markup)}"
    )


def _setting(key: str, value: SettingValue, markup: Markup) -> str:
    if isinstance(value, IndexPlan):
        return f"{markup.setting(value.column)} ({markup.text(value.kind)}{', ' + markup.text(value.unit) if value.unit else ''})"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if value is None:
        return "row_index (generated)" if key == "index" else DASH
    return markup.setting(value)


def source_cells(source: SourceEntry, markup: Markup) -> list[str]:
    """A source's row: name, kind, file, what it reads (its settings), how many values."""
    reads = "; ".join(f"{key}: {_setting(key, value, markup)}" for key, value in source.settings.items())
    return [markup.code(source.name), markup.text(source.kind), markup.path(source.file.relative), reads, markup.count(len(source.names))]


def robot_items(robot: RobotEntry, sample: SampleEntry | None, markup: Markup) -> list[str]:
    """What a robot's section lists before its joint table: its URDF, frames, joints source, ignored values, sample."""
    counts, prefix = robot.joint_counts, markup.code(robot.frame_prefix) if robot.frame_prefix else "none"
    items = [
        f"URDF: {markup.path(robot.urdf.origin)}, sha256 {markup.code(robot.urdf.sha256)}",
        f"entity path {markup.code(robot.entity_path_prefix)}, frame prefix {prefix}, root frame {markup.code(robot.root_frame)}, "
        f"collision geometries {'kept' if robot.collision_geometries == 'keep' else 'dropped'}",
        "URDF joints: "
        + ", ".join(f"{markup.count(counts[kind])} {kind}" for kind in JOINT_TYPES)
        + f"; {markup.count(counts['mimic'])} mimic",
        *([markup.code(robot.copy_text)] if robot.copy_text else []),
    ]
    if robot.source is None:
        return [*items, "a scene: no moving joints, no joint source (static transforms only)"]
    items.append(
        f"joints from source {markup.code(robot.source)}; NaN policy {markup.code(str(robot.nan_policy))}; "
        f"values beyond the slack: {markup.code(str(robot.on_violation))}"
    )
    items.append("ignored source values: " + (markup.names(robot.ignored_source_values) if robot.ignored_source_values else "none"))
    if sample is not None:
        read = sample.read.get(robot.source, 0)
        items.append(
            f"sampled: the first {plural(read, 'row', markup)} of source {markup.code(robot.source)} (at most {markup.count(sample.rows)})"
        )
    return items


def joint_cells(row: JointRow, markup: Markup, sampled: bool) -> list[str]:
    """A joint's row: its source value, joint, type, unit, sign, offset, map, limits, driver (and what --sample saw)."""
    cells = [
        markup.code(row.source_name) if row.source_name is not None else DASH,
        markup.code(row.joint),
        markup.text(row.type),
        markup.text(row.unit) if row.unit else DASH,
        number(row.sign) if row.sign is not None else DASH,
        number(row.offset) if row.offset is not None else DASH,
        map_cell(row),
        limits_cell(row, markup),
        driver_cell(row, markup),
    ]
    return [*cells, observed_cell(row.observed, markup)] if sampled else cells


def warning_items(report: PlanReport, markup: Markup, message: Callable[[str], str]) -> list[str]:
    """Each warning where it is (file, line, column, key path) and what it says, `message` as the format bounds it."""
    items = []
    for warning in report.warnings:
        place = warning.file or report.config.relative
        if warning.line:
            place += f":{warning.line}" + (f":{warning.column}" if warning.column else "")
        path = f" {markup.path(warning.path)}" if warning.path else ""
        items.append(f"{markup.path(place)}{path}: {message(warning.message)}")
    return items


def _numbers(values: Sequence[float]) -> str:
    return ", ".join(number(v) for v in values)


def edge_cells(edge: EdgeEntry, markup: Markup, origin: Callable[[object], str]) -> list[str]:
    """An edge's row: parent, child, translation, rotation (a temporal edge: the columns it reads), and `origin` (its
    description, free text from the config) as the renderer writes such text."""
    temporal = edge.temporal
    if temporal is not None and temporal.tf_topic is not None:  # a bag's /tf edge: the child's transforms, no named values
        translation = f"per message: the bag's {markup.code(temporal.tf_topic)} of source {markup.code(temporal.source or '')}"
        rotation = "per message: the same transforms"
    elif temporal is not None:
        translation = "per row: " + ", ".join(markup.code(n) for n in temporal.translation_names)
        rotation = "per row: quaternion_xyzw " + ", ".join(markup.code(n) for n in temporal.quaternion_names)
    else:
        translation, rotation = _numbers(edge.translation or ()), _numbers(edge.rotation_rpy_deg or ())
    return [markup.code(edge.parent), markup.code(edge.child), translation, rotation, origin(edge.origin.description)]


def map_cell(row: JointRow) -> str:
    """The value conversion beyond unit, sign and offset: wrap, source_range, scale."""
    parts = []
    if row.wrap is not None:
        parts.append(f"wrap {number(row.wrap.period)} around {number(row.wrap.center)}")
    if row.source_range is not None:
        parts.append(f"source_range [{_numbers(row.source_range)}] → [{_numbers(row.target_range or ())}]")
    elif row.scale is not None and rounded(row.scale) != 1:
        parts.append(f"× {number(row.scale)}")
    return "; ".join(parts) or DASH


def limits_cell(row: JointRow, markup: Markup) -> str:
    if row.kind != "mapped":
        return DASH
    if row.limits_source_units is None:
        return "none"
    low, high = row.limits_source_units
    return f"{number(low)} .. {number(high)}" + (f" ± {markup.text(row.slack_text)}" if row.slack_text != "0" else "")


def driver_cell(row: JointRow, markup: Markup) -> str:
    if row.kind == "held" and row.hold is not None:
        return markup.literal(f"hold = {number(row.hold)}")
    if row.kind == "mimic" and row.mimic is not None:
        return f"{markup.code(row.mimic.driver)} × {number(row.mimic.multiplier)} + {number(row.mimic.offset)}"
    return DASH


def observed_cell(observed: Observed | None, markup: Markup) -> str:
    """The sampled range and whether it fits the limits (`plan --sample`)."""
    if observed is None:
        return DASH
    if observed.min is None or observed.max is None:
        return f"no finite values in {markup.count(observed.rows)} rows"
    if observed.verdict == "no limits":
        status = "no limits"
    elif not observed.fits:
        status = markup.bad("outside the limits")
    elif observed.slack_rows:
        status = f"fits; {markup.count(observed.slack_rows)} rows within the slack"
    else:
        status = markup.good("fits")
    return f"{number(observed.min)} .. {number(observed.max)} ({status})"


def output_items(output: OutputEntry, markup: Markup) -> list[str]:
    """What the run writes: layout, model, manifest, series, and the line that heads the segment table."""
    items = [f"layout {markup.code(output.layout)}, application_id {markup.code(output.application_id)}"]
    if output.model is not None:
        items.append(f"model (meshes, static URDF transforms, written once, static only): {markup.path(output.model.relative)}")
    items.append(f"manifest: {markup.path(output.manifest.relative)}")
    if output.joint_series:
        items.append(f"{SERIES_TEXT} ({markup.code('output.joint_series')})")
    for trail in output.trails:
        where = f"{markup.code(trail.robot)}'s {markup.code(trail.link)} in {markup.code(trail.frame)}"
        items.append(f"trail of {where}: {trail.style}, window {trail.window} ({markup.code('trails')})")
    what = "layer (forward kinematics, calibration edges)" if output.layout == "split" else "recording"
    items.append(f"{plural(output.segment_count, 'segment', markup)}, each a {what} whose recording_id is the segment id:")
    return items


def segment_cells(segment: SegmentEntry, markup: Markup) -> list[str]:
    """One row of the segment table: id, input (episode, file), frames, output."""
    source = f"episode {segment.episode}" if segment.episode is not None else ""
    if segment.stem is not None:
        source = f"file {markup.code(segment.stem)}" + (f" ({source})" if source else "")
    frames = markup.count(segment.frames) if segment.frames is not None else DASH
    return [markup.code(segment.id), source or DASH, frames, markup.path(segment.output.relative)]

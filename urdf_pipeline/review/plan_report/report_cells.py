"""The joint and edge tables' cells and the output section that Markdown and HTML share: what a cell says is decided once, here; each renderer gives
its own markup (`Markup`) for names, free text, verdicts and counts."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from .report_model import SERIES_TEXT, EdgeEntry, JointRow, Observed, OutputEntry, SegmentEntry, number, rounded

DASH = "—"


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
    count = output.segment_count
    items.append(f"{markup.count(count)} segment{'' if count == 1 else 's'}, each a {what} whose recording_id is the segment id:")
    return items


def segment_cells(segment: SegmentEntry, markup: Markup) -> list[str]:
    """One row of the segment table: id, input (episode, file), frames, output."""
    source = f"episode {segment.episode}" if segment.episode is not None else ""
    if segment.stem is not None:
        source = f"file {markup.code(segment.stem)}" + (f" ({source})" if source else "")
    frames = markup.count(segment.frames) if segment.frames is not None else DASH
    return [markup.code(segment.id), source or DASH, frames, markup.path(segment.output.relative)]

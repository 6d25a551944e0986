"""The plan report as Markdown, for a pull-request comment: tables per source, robot and edge, the frame tree."""

from __future__ import annotations

from collections.abc import Sequence

from ...errors import LINE_LIMIT, neutral_text
from ...plan import IndexPlan
from ..markdown_text import cell, code, code_path, fence_for, link_target, plain
from .report_cells import Markup, driver_cell, edge_cells, limits_cell, map_cell, observed_cell, output_items, segment_cells
from .report_model import (
    JOINT_TYPES,
    OutputEntry,
    PictureEntry,
    PlanReport,
    RobotEntry,
    SampleEntry,
    SourceEntry,
    number,
)

MARKDOWN_SEGMENTS = 20  # segment rows shown in markdown; json lists them all
MARKDOWN_NAMES = 24  # names in one line of a list (ignored source values); json lists them all
DASH = "—"
ORDER_NOTE = (
    "Per source value, in this order: wrap (source units) → value × unit factor × scale × sign + offset (offset in URDF "
    "units), or source_range mapped onto the joint's range → limits (clamped within the slack) → mimic joints. "
    "Limits in source units are the raw values these corrections send onto the URDF limits, low to high (as "
    "`urdf-pipeline check` and a run's limit error show them)."
)
_n = number


_code = code  # every name from the config, URDF or data is a code span (markdown_text.py: inert whatever it holds)
MARKUP = Markup(
    code=_code, path=code_path, text=str, literal=lambda expression: f"`{expression}`", bad=lambda word: f"**{word}**", good=str, count=str
)


def _names(names: Sequence[str]) -> str:
    """Code spans, the first MARKDOWN_NAMES of them: one line stays readable however many names there are."""
    more = f" and {len(names) - MARKDOWN_NAMES:,} more" if len(names) > MARKDOWN_NAMES else ""
    return ", ".join(_code(name) for name in names[:MARKDOWN_NAMES]) + more


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(cell(text) for text in cells) + " |"

    return [line(header), line(["---"] * len(header)), *(line(row) for row in rows)]


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def _source_details(source: SourceEntry) -> str:
    parts = []
    for key, value in source.settings.items():
        if isinstance(value, IndexPlan):
            shown = f"{plain(value.column)} ({value.kind}{', ' + value.unit if value.unit else ''})"
        elif isinstance(value, bool):
            shown = "yes" if value else "no"
        elif value is None:
            shown = "row_index (generated)" if key == "index" else DASH
        else:
            shown = plain(value)  # a dataset, column, topic, ... as the config names it
        parts.append(f"{key}: {shown}")
    return "; ".join(parts)


def _robot_markdown(robot: RobotEntry, sample: SampleEntry | None) -> list[str]:
    counts = robot.joint_counts
    prefix = _code(robot.frame_prefix) if robot.frame_prefix else "none"
    lines = [
        f"#### Robot {_code(robot.key)}: URDF {_code(robot.robot_name)}",
        "",
        f"- URDF: {code_path(robot.urdf.origin)}, sha256 {_code(robot.urdf.sha256)}",
        f"- entity path {_code(robot.entity_path_prefix)}, frame prefix {prefix}, root frame {_code(robot.root_frame)}, "
        f"collision geometries {'kept' if robot.collision_geometries == 'keep' else 'dropped'}",
        "- URDF joints: " + ", ".join(f"{counts[kind]} {kind}" for kind in JOINT_TYPES) + f"; {counts['mimic']} mimic",
        *([f"- {_code(robot.copy_text)}"] if robot.copy_text else []),
    ]
    if robot.source is None:
        return [*lines, "- a scene: no moving joints, no joint source (static transforms only)", ""]
    lines.append(
        f"- joints from source {_code(robot.source)}; NaN policy {_code(str(robot.nan_policy))}; "
        f"values beyond the slack: {_code(str(robot.on_violation))}"
    )
    ignored = robot.ignored_source_values
    lines.append("- ignored source values: " + (_names(ignored) if ignored else "none"))
    if sample is not None:
        read = sample.read.get(robot.source, 0)
        lines.append(f"- sampled: the first {_plural(read, 'row')} of source {_code(robot.source)} (at most {sample.rows})")
    header = [
        "source name", "URDF joint", "type", "unit", "sign", "offset (URDF units)", "scale / range map", "limits (source units)", "mimic driver / hold",
    ]  # fmt: skip
    if sample is not None:
        header.append("observed (source units)")
    rows = []
    for row in robot.joints:
        cells = [
            _code(row.source_name) if row.source_name is not None else DASH,
            _code(row.joint),
            row.type,
            row.unit or DASH,
            _n(row.sign) if row.sign is not None else DASH,
            _n(row.offset) if row.offset is not None else DASH,
            map_cell(row),
            limits_cell(row, MARKUP),
            driver_cell(row, MARKUP),
        ]
        if sample is not None:
            cells.append(observed_cell(row.observed, MARKUP))
        rows.append(cells)
    return [*lines, "", *_table(header, rows), ""]


def _output_markdown(output: OutputEntry) -> list[str]:
    lines = ["#### Output", "", *(f"- {item}" for item in output_items(output, MARKUP))]
    rows = [segment_cells(segment, MARKUP) for segment in output.segments[:MARKDOWN_SEGMENTS]]
    hidden = output.segment_count - len(rows)
    if hidden > 0:
        rows.append([f"… {hidden} more", "", "", ""])
    return [*lines, "", *_table(["segment", "input", "frames", "output"], rows), ""]


def pictures_markdown(pictures: Sequence[PictureEntry], note: str) -> list[str]:
    """Links to the pictures `--render` drew (their paths as given: the reader opens them beside the text), each
    label plain text and each path percent-encoded, whatever the config's file name holds."""
    if not pictures:
        return []
    return [f"{note} " + " · ".join(f"[{plain(picture.label)}]({link_target(picture.path)})" for picture in pictures), ""]


def _pictures_markdown(pictures: Sequence[PictureEntry]) -> list[str]:
    return pictures_markdown(pictures, "Pictures (the rest pose, drawn by the Rerun viewer):")


def render_markdown(report: PlanReport) -> str:
    edges, robots, sources = report.edges, report.robots, report.sources_by_name
    configured = sum(1 for e in edges if not e.origin.kind.startswith("urdf_"))
    segments = report.output.segment_count
    config = report.config.relative
    lines = [
        f"### urdf-pipeline plan: {code_path(config)}",
        "",
        f"Root frame {_code(report.root_frame)}; {_plural(len(robots), 'robot')}, {_plural(len(sources), 'source')}, "
        f"{_plural(len(edges), 'edge')} ({configured} from the config, {len(edges) - configured} URDF joints), "
        f"{_plural(segments, 'segment')}.",
        "",
        *_pictures_markdown(report.pictures),
        "#### Sources" + (" (the first segment's)" if segments > 1 else ""),
        "",
        *_table(
            ["source", "kind", "file", "reads", "values"],
            [[_code(s.name), s.kind, code_path(s.file.relative), _source_details(s), str(len(s.names))] for s in sources],
        ),
        "",
    ]
    if any(robot.joints for robot in robots):
        lines += [f"> {ORDER_NOTE}", ""]
    for robot in robots:
        lines += _robot_markdown(robot, report.sample)
    lines += [
        "#### Edges",
        "",
        "Every edge of the frame graph, top down from the root. URDF moving joints are shown at their origin (joint value 0); "
        "the run logs their pose per row.",
        "",
        *_table(["parent", "child", "translation (m)", "rotation (rpy deg)", "origin"], [edge_cells(e, MARKUP, plain) for e in edges]),
        "",
        "#### Frame tree",
        "",
        fence_for(report.frame_tree.mermaid) + "mermaid",
        report.frame_tree.mermaid,
        fence_for(report.frame_tree.mermaid),
        "",
        "`-->` URDF moving joint, `-.->` URDF fixed joint, `==>` an edge of the config (`-.->` when its identity is assumed).",
        "",
        *_output_markdown(report.output),
        "#### Warnings",
        "",
    ]
    if not report.warnings:
        lines.append("None.")
    for warning in report.warnings:
        place = warning.file or config
        if warning.line:
            place += f":{warning.line}" + (f":{warning.column}" if warning.column else "")
        path = f" {code_path(warning.path)}" if warning.path else ""
        lines.append(f"- {code_path(place)}{path}: {plain(warning.message, LINE_LIMIT // 2)}")
    return neutral_text("\n".join(lines) + "\n")  # the last guard: no line a workflow command, none unbounded

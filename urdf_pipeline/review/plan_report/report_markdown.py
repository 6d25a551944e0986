"""The plan report as Markdown, for a pull-request comment: tables per source, robot and edge, the frame tree."""

from __future__ import annotations

from collections.abc import Sequence

from ...errors import LINE_LIMIT, neutral_text
from ..markdown_text import cell, code, code_path, fence_for, link_target, plain
from .report_cells import (
    EDGE_HEADER,
    EDGES_NOTE,
    JOINT_HEADER,
    ORDER_NOTE,
    SOURCE_HEADER,
    Markup,
    edge_cells,
    joint_cells,
    output_items,
    robot_items,
    segment_cells,
    source_cells,
    summary,
    warning_items,
)
from .report_model import OutputEntry, PictureEntry, PlanReport, RobotEntry, SampleEntry

MARKDOWN_SEGMENTS = 20  # segment rows shown in markdown; json lists them all
MARKDOWN_NAMES = 24  # names in one line of a list (ignored source values); json lists them all

# every name from the config, URDF or data is a code span (markdown_text.py: inert whatever it holds)
MARKUP = Markup(
    code=code,
    path=code_path,
    text=str,
    literal=lambda expression: f"`{expression}`",
    bad=lambda word: f"**{word}**",
    good=str,
    count=str,
    setting=plain,
    names_shown=MARKDOWN_NAMES,
)


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(cell(text) for text in cells) + " |"

    return [line(header), line(["---"] * len(header)), *(line(row) for row in rows)]


def _robot_markdown(robot: RobotEntry, sample: SampleEntry | None) -> list[str]:
    lines = [
        f"#### Robot {code(robot.key)}: URDF {code(robot.robot_name)}",
        "",
        *(f"- {item}" for item in robot_items(robot, sample, MARKUP)),
    ]
    if robot.source is None:
        return [*lines, ""]
    header = [*JOINT_HEADER, *(["observed (source units)"] if sample is not None else [])]
    return [*lines, "", *_table(header, [joint_cells(row, MARKUP, sample is not None) for row in robot.joints]), ""]


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


def render_markdown(report: PlanReport) -> str:
    segments = report.output.segment_count
    lines = [
        f"### urdf-pipeline plan: {code_path(report.config.relative)}",
        "",
        f"{summary(report, MARKUP)}.",
        "",
        *pictures_markdown(report.pictures, "Pictures (the rest pose, drawn by the Rerun viewer):"),
        "#### Sources" + (" (the first segment's)" if segments > 1 else ""),
        "",
        *_table(SOURCE_HEADER, [source_cells(s, MARKUP) for s in report.sources_by_name]),
        "",
    ]
    if any(robot.joints for robot in report.robots):
        lines += [f"> {ORDER_NOTE} (as `urdf-pipeline check` and a run's limit error show them).", ""]
    for robot in report.robots:
        lines += _robot_markdown(robot, report.sample)
    lines += [
        "#### Edges",
        "",
        EDGES_NOTE,
        "",
        *_table(EDGE_HEADER, [edge_cells(e, MARKUP, plain) for e in report.edges]),
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
        *(f"- {item}" for item in warning_items(report, MARKUP, lambda message: plain(message, LINE_LIMIT // 2))),
    ]
    if not report.warnings:
        lines.append("None.")
    return neutral_text("\n".join(lines) + "\n")  # the last guard: no line a workflow command, none unbounded

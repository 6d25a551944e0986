"""`diff`'s report (diff_base.DiffReport) as text, one line per change, as JSON for tools, or as Markdown for a
pull-request comment (the changes, and links to the pictures of `--render`)."""

from __future__ import annotations

import json
from typing import Any, Literal

from ...errors import LINE_LIMIT, neutral_text, shown
from ..markdown_text import code, code_path
from ..plan_report.report_markdown import pictures_markdown
from .diff_base import Change, DiffReport

DiffFormat = Literal["text", "json", "markdown"]


def render_text(report: DiffReport) -> str:
    """One line per change (each neutral: names from the configs hold no newline or control character, forge no
    workflow command, and a long one is shortened); the empty string when there is none."""
    return neutral_text("".join(shown(change.line, LINE_LIMIT) + "\n" for change in report.changes))


def _change(change: Change) -> dict[str, Any]:
    return {
        "group": change.group,
        "subject": change.subject,
        "detail": shown(change.detail, LINE_LIMIT),  # words for a person, bounded; old and new are the values as they are
        "old": change.old,
        "new": change.new,
        "line": shown(change.line, LINE_LIMIT),
    }


def render_json(report: DiffReport) -> str:
    data: dict[str, Any] = {
        "old": report.old,
        "new": report.new,
        "equivalent": report.equivalent,
        "changes": [_change(c) for c in report.changes],
    }
    if report.pictures:
        data["pictures"] = [{"label": p.label, "path": p.path} for p in report.pictures]
    return json.dumps(data, indent=2) + "\n"


def render_markdown(report: DiffReport) -> str:
    count = len(report.changes)
    lines = [
        f"**urdf-pipeline diff** {code_path(report.old)} → {code_path(report.new)}: "
        + (f"{count} change(s)" if count else "no semantic difference"),
        "",
    ]
    lines += [f"- {code(change.line, LINE_LIMIT // 2)}" for change in report.changes]
    if report.changes:
        lines.append("")
    lines += pictures_markdown(
        report.pictures, "Pictures (old and new at the same joint values, one camera; the overlay: old as a blue ghost):"
    )
    return "\n".join(lines).rstrip("\n") + "\n"


def render_diff(report: DiffReport, format: DiffFormat) -> str:
    return {"json": render_json, "markdown": render_markdown}.get(format, render_text)(report)

"""`diff`'s report (diff_base.DiffReport) as text, one line per change, as JSON for tools, or as Markdown for a
pull-request comment (the changes, and links to the pictures of `--render`)."""

from __future__ import annotations

import json
from typing import Any, Literal

from .diff_base import Change, DiffReport
from .report_markdown import pictures_markdown

DiffFormat = Literal["text", "json", "markdown"]


def render_text(report: DiffReport) -> str:
    """One line per change; the empty string when there is none."""
    return "".join(change.line + "\n" for change in report.changes)


def _change(change: Change) -> dict[str, Any]:
    return {
        "group": change.group,
        "subject": change.subject,
        "detail": change.detail,
        "old": change.old,
        "new": change.new,
        "line": change.line,
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


def _code(text: str) -> str:
    """A Markdown code span that survives backticks inside the text."""
    fence = "``" if "`" in text else "`"
    return f"{fence} {text} {fence}" if fence == "``" else f"`{text}`"


def render_markdown(report: DiffReport) -> str:
    count = len(report.changes)
    lines = [
        f"**urdf-pipeline diff** {_code(report.old)} → {_code(report.new)}: "
        + (f"{count} change(s)" if count else "no semantic difference"),
        "",
    ]
    lines += [f"- {_code(change.line)}" for change in report.changes]
    if report.changes:
        lines.append("")
    lines += pictures_markdown(report.pictures, "Pictures (old and new at the same joint values, one camera):")
    return "\n".join(lines).rstrip("\n") + "\n"


def render_diff(report: DiffReport, format: DiffFormat) -> str:
    return {"json": render_json, "markdown": render_markdown}.get(format, render_text)(report)

"""`diff`'s report (diff_base.DiffReport) as text, one line per change, or as JSON for tools."""

from __future__ import annotations

import json
from typing import Any, Literal

from .diff_base import Change, DiffReport

DiffFormat = Literal["text", "json"]


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
    data = {"old": report.old, "new": report.new, "equivalent": report.equivalent, "changes": [_change(c) for c in report.changes]}
    return json.dumps(data, indent=2) + "\n"


def render_diff(report: DiffReport, format: DiffFormat) -> str:
    return render_json(report) if format == "json" else render_text(report)

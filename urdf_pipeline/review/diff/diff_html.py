"""`diff`'s report (diff_base.DiffReport) as HTML, for `diff --html`: the changes grouped (robots, edges, sources,
output), one row each, and the pictures of `--render`. Every string from the configs goes through `web.html_text`."""

from __future__ import annotations

from itertools import groupby

from ...errors import LINE_LIMIT
from ...web import html_text
from ..plan_report.report_cells import plural
from ..plan_report.report_html import MARKUP, code, pictures_html, table
from .diff_base import DiffReport

GROUPS = {"robot": "Robots", "edges": "Edges", "sources": "Sources", "output": "Output"}


def render_diff_html(report: DiffReport, at: str = "index.html", viewer_html: str = "") -> str:
    """The diff as the body of the page at site path `at`; `viewer_html` (old and new in the site's viewer) goes
    after the summary."""
    count = len(report.changes)
    summary = f"{plural(count, 'change', MARKUP)} in the compiled plans." if count else "No semantic difference between the compiled plans."
    lines = [
        f"<h1>Diff of {code(report.old)} → {code(report.new)}</h1>",
        f"<p>{summary} Key order, comments and equal spellings do not count.</p>",
        viewer_html,
        '<h2 id="pictures">Pictures</h2>',
        pictures_html(report.pictures, at, "Old and new at the same joint values, from one camera, drawn by the Rerun viewer."),
        '<h2 id="changes">Changes</h2>',
    ]
    if not count:
        lines.append("<p>None.</p>")
    for group, changes in groupby(report.changes, key=lambda change: change.group):
        rows = [[code(change.subject), html_text(change.detail, LINE_LIMIT)] for change in changes]
        lines += [f"<h3>{html_text(GROUPS.get(group, group))}</h3>", table(["what", "change"], rows)]
    return "\n".join(line for line in lines if line) + "\n"

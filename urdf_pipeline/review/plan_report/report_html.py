"""The plan report as HTML, for `plan --html`: the same model as text, markdown and json (report_model.PlanReport),
as the body of the site's index page. Every string from the config, URDF, data or a file name goes through
`web.html_text` (escaped, one line, shortened); links are relative site paths (`web.relative_href`)."""

from __future__ import annotations

from collections.abc import Sequence

from ...web import html_text, relative_href
from ..markdown_text import PATH_LIMIT
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
    plural,
    robot_items,
    segment_cells,
    source_cells,
    summary,
    warning_items,
)
from .report_model import EdgeEntry, OutputEntry, PictureEntry, PlanReport, RobotEntry, SampleEntry

HTML_SEGMENTS = 500  # segment rows on the page; json lists them all
HTML_NAMES = 100  # names in one list (ignored source values)
PICTURES_PER_ROW = 2  # side by side on the page, each a link to its full size
TREE_DEPTH = 40  # indentation levels of the frame tree; deeper frames say their depth
NO_PICTURES = (
    "No pictures in this site: run the command with <code>--render DIR</code> as well, and the Rerun viewer draws them "
    "(headless; it needs a Vulkan driver, e.g. <code>apt-get install mesa-vulkan-drivers</code>)."
)
TREE_LABELS = {
    "urdf_moving_joint": "URDF moving joint",
    "urdf_fixed_joint": "URDF fixed joint",
    "calibration_inline": "calibration",
    "calibration_file": "calibration file",
    "fixed_chain": "fixed chain",
    "assumed_identity": "identity ASSUMED",
    "temporal": "temporal edge",
}


def text(value: object, limit: int = PATH_LIMIT) -> str:
    """Text from input, escaped (`web.html_text`): a message, a path, a setting's value."""
    return html_text(value, limit)


def code(value: object, limit: int = PATH_LIMIT) -> str:
    """A name from input as inline code."""
    return f"<code>{html_text(value, limit)}</code>"


MARKUP = Markup(
    code=code,
    path=code,
    text=text,
    literal=str,
    bad=lambda word: f'<strong class="bad">{word}</strong>',
    good=lambda word: f'<span class="good">{word}</span>',
    count=lambda rows: f"{rows:,}",
    setting=code,
    names_shown=HTML_NAMES,
)


def table(header: Sequence[str], rows: Sequence[Sequence[str]], numbers: Sequence[int] = ()) -> str:
    """A table whose header and cells are HTML already; `numbers`: columns aligned right."""

    def cells(tag: str, values: Sequence[str]) -> str:
        return "".join(f'<{tag} class="number">{v}</{tag}>' if i in numbers else f"<{tag}>{v}</{tag}>" for i, v in enumerate(values))

    body = "\n".join(f"<tr>{cells('td', row)}</tr>" for row in rows)
    return f"<table>\n<thead><tr>{cells('th', header)}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


def pictures_html(pictures: Sequence[PictureEntry], at: str, note: str) -> str:
    """The pictures of `--render`, inline (their paths are site paths here), or what to do to get them."""
    if not pictures:
        return f'<p class="muted">{NO_PICTURES}</p>'
    figures = []
    for picture in pictures:
        href = relative_href(at, picture.path)
        figures.append(
            f'<td><figure><a href="{href}"><img src="{href}" alt="{text(picture.label)}" loading="lazy"></a>'
            f"<figcaption>{text(picture.label)}</figcaption></figure></td>"
        )
    rows = ["<tr>" + "".join(figures[i : i + PICTURES_PER_ROW]) + "</tr>" for i in range(0, len(figures), PICTURES_PER_ROW)]
    return f'<p class="muted">{note} Click one for its full size.</p>\n<table class="pictures">\n' + "\n".join(rows) + "\n</table>"


def _robot(robot: RobotEntry, sample: SampleEntry | None) -> list[str]:
    items = [
        f"<h3>Robot {code(robot.key)}: URDF {code(robot.robot_name)}</h3>",
        "<ul>",
        *(f"<li>{i}</li>" for i in robot_items(robot, sample, MARKUP)),
    ]
    if robot.source is None:
        return [*items, "</ul>"]
    header = [*JOINT_HEADER, *(["observed (source units)"] if sample is not None else [])]
    return [*items, "</ul>", table(header, [joint_cells(row, MARKUP, sample is not None) for row in robot.joints])]


def frame_tree(root: str, edges: Sequence[EdgeEntry]) -> str:
    """The frame tree top down (the edges come depth first from the root), one frame a line, indented by depth."""
    depth = {root: 0}
    lines = [code(root)]
    for edge in edges:
        level = depth.get(edge.parent, 0) + 1
        depth.setdefault(edge.child, level)
        indent = "  " * min(level - 1, TREE_DEPTH) + "└ "
        deeper = f" (depth {level:,})" if level > TREE_DEPTH else ""
        lines.append(f'{indent}{code(edge.child)} <span class="muted">{TREE_LABELS[edge.origin.kind]}{deeper}</span>')
    return '<pre class="tree">' + "\n".join(lines) + "</pre>"


def _output(output: OutputEntry) -> list[str]:
    items = output_items(output, MARKUP)
    rows = [segment_cells(segment, MARKUP) for segment in output.segments[:HTML_SEGMENTS]]
    hidden = output.segment_count - len(rows)
    if hidden > 0:
        rows.append([f"… {hidden:,} more (all in <code>plan --format json</code>)", "", "", ""])
    lines = ['<h2 id="output">Output</h2>', "<ul>", *(f"<li>{item}</li>" for item in items), "</ul>"]
    return [*lines, table(["segment", "input", "frames", "output"], rows, numbers=(2,))]


def _warnings(report: PlanReport) -> list[str]:
    items = [f"<li>{item}</li>" for item in warning_items(report, MARKUP, text)]
    return ['<h2 id="warnings">Warnings</h2>', *(["<ul>", *items, "</ul>"] if items else ["<p>None.</p>"])]


def render_html(report: PlanReport, at: str = "index.html", viewer_html: str = "") -> str:
    """The report as the body of the page at site path `at`; `viewer_html` (the caller's: the rest pose in the site's
    viewer) goes after the summary."""
    lines = [
        f"<h1>Plan of {code(report.config.relative)}</h1>",
        f"<p>{summary(report, MARKUP)}; {plural(len(report.warnings), 'warning', MARKUP)}.</p>",
        viewer_html,
        '<h2 id="pictures">Pictures</h2>',
        pictures_html(report.pictures, at, "The rest pose, drawn by the Rerun viewer."),
        '<h2 id="sources">Sources' + (" (the first segment's)" if report.output.segment_count > 1 else "") + "</h2>",
        table(SOURCE_HEADER, [source_cells(s, MARKUP) for s in report.sources_by_name], numbers=(4,)),
        '<h2 id="robots">Robots</h2>',
    ]
    if any(robot.joints for robot in report.robots):
        lines.append(f'<p class="muted">{ORDER_NOTE}.</p>')
    for robot in report.robots:
        lines += _robot(robot, report.sample)
    lines += [
        '<h2 id="edges">Edges</h2>',
        f"<p>{EDGES_NOTE}</p>",
        table(EDGE_HEADER, [edge_cells(e, MARKUP, text) for e in report.edges]),
        '<h2 id="tree">Frame tree</h2>',
        frame_tree(report.root_frame, report.edges),
        *_output(report.output),
        *_warnings(report),
    ]
    return "\n".join(line for line in lines if line) + "\n"

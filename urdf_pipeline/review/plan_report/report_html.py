"""The plan report as HTML, for `plan --html`: the same model as text, markdown and json (report_model.PlanReport),
as the body of the site's index page. Every string from the config, URDF, data or a file name goes through
`web.html_text` (escaped, one line, shortened); links are relative site paths (`web.relative_href`)."""

from __future__ import annotations

from collections.abc import Sequence

from ...plan import IndexPlan
from ...web import html_text, relative_href
from ..markdown_text import PATH_LIMIT
from .report_cells import Markup, driver_cell, edge_cells, limits_cell, map_cell, observed_cell, output_items, segment_cells
from .report_model import (
    JOINT_TYPES,
    EdgeEntry,
    JointRow,
    OutputEntry,
    PictureEntry,
    PlanReport,
    RobotEntry,
    SampleEntry,
    SourceEntry,
    number,
)

HTML_SEGMENTS = 500  # segment rows on the page; json lists them all
HTML_NAMES = 100  # names in one list (ignored source values)
PICTURES_PER_ROW = 2  # side by side on the page, each a link to its full size
TREE_DEPTH = 40  # indentation levels of the frame tree; deeper frames say their depth
DASH = "—"
NO_PICTURES = (
    "No pictures in this site: run the command with <code>--render DIR</code> as well, and the Rerun viewer draws them "
    "(headless; it needs a Vulkan driver, e.g. <code>apt-get install mesa-vulkan-drivers</code>)."
)
ORDER_NOTE = (
    "Per source value, in this order: wrap (source units) → value × unit factor × scale × sign + offset (offset in URDF "
    "units), or source_range mapped onto the joint's range → limits (clamped within the slack) → mimic joints. Limits in "
    "source units are the raw values these corrections send onto the URDF limits, low to high."
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
)


def table(header: Sequence[str], rows: Sequence[Sequence[str]], numbers: Sequence[int] = ()) -> str:
    """A table whose header and cells are HTML already; `numbers`: columns aligned right."""

    def cells(tag: str, values: Sequence[str]) -> str:
        return "".join(f'<{tag} class="number">{v}</{tag}>' if i in numbers else f"<{tag}>{v}</{tag}>" for i, v in enumerate(values))

    body = "\n".join(f"<tr>{cells('td', row)}</tr>" for row in rows)
    return f"<table>\n<thead><tr>{cells('th', header)}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


def plural(count: int, word: str) -> str:
    return f"{count:,} {word}{'' if count == 1 else 's'}"


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


def _setting(key: str, value: object) -> str:
    if isinstance(value, IndexPlan):
        return f"{code(value.column)} ({text(value.kind)}{', ' + text(value.unit) if value.unit else ''})"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if value is None:
        return "row_index (generated)" if key == "index" else DASH
    return code(value)


def _sources(sources: Sequence[SourceEntry], many_segments: bool) -> list[str]:
    rows = [
        [
            code(s.name),
            text(s.kind),
            code(s.file.relative),
            "; ".join(f"{text(key)}: {_setting(key, value)}" for key, value in s.settings.items()),
            f"{len(s.names):,}",
        ]
        for s in sources
    ]
    heading = "Sources" + (" (the first segment's)" if many_segments else "")
    return [f'<h2 id="sources">{heading}</h2>', table(["source", "kind", "file", "reads", "values"], rows, numbers=(4,))]


def _names(names: Sequence[str]) -> str:
    more = f" and {len(names) - HTML_NAMES:,} more" if len(names) > HTML_NAMES else ""
    return ", ".join(code(name) for name in names[:HTML_NAMES]) + more


def _joint_cells(row: JointRow, sample: SampleEntry | None) -> list[str]:
    cells = [
        code(row.source_name) if row.source_name is not None else DASH,
        code(row.joint),
        text(row.type),
        text(row.unit) if row.unit else DASH,
        number(row.sign) if row.sign is not None else DASH,
        number(row.offset) if row.offset is not None else DASH,
        map_cell(row),
        limits_cell(row, MARKUP),
        driver_cell(row, MARKUP),
    ]
    return [*cells, observed_cell(row.observed, MARKUP)] if sample is not None else cells


def _robot(robot: RobotEntry, sample: SampleEntry | None) -> list[str]:
    counts = robot.joint_counts
    prefix = code(robot.frame_prefix) if robot.frame_prefix else "none"
    items = [
        f"URDF {code(robot.urdf.origin)}, sha256 {code(robot.urdf.sha256)}",
        f"entity path {code(robot.entity_path_prefix)}, frame prefix {prefix}, root frame {code(robot.root_frame)}, "
        f"collision geometries {'kept' if robot.collision_geometries == 'keep' else 'dropped'}",
        "URDF joints: " + ", ".join(f"{counts[kind]:,} {kind}" for kind in JOINT_TYPES) + f"; {counts['mimic']:,} mimic",
        *([code(robot.copy_text)] if robot.copy_text else []),
    ]
    lines = [f"<h3>Robot {code(robot.key)}: URDF {code(robot.robot_name)}</h3>"]
    if robot.source is None:
        items.append("a scene: no moving joints, no joint source (static transforms only)")
        return [*lines, "<ul>", *(f"<li>{item}</li>" for item in items), "</ul>"]
    items.append(
        f"joints from source {code(robot.source)}; NaN policy {code(str(robot.nan_policy))}; "
        f"values beyond the slack: {code(str(robot.on_violation))}"
    )
    items.append("ignored source values: " + (_names(robot.ignored_source_values) if robot.ignored_source_values else "none"))
    if sample is not None:
        read = sample.read.get(robot.source, 0)
        items.append(f"sampled: the first {plural(read, 'row')} of source {code(robot.source)} (at most {sample.rows:,})")
    header = ["source name", "URDF joint", "type", "unit", "sign", "offset (URDF units)", "scale / range map"]
    header += ["limits (source units)", "mimic driver / hold", *(["observed (source units)"] if sample is not None else [])]
    rows = [_joint_cells(row, sample) for row in robot.joints]
    return [*lines, "<ul>", *(f"<li>{item}</li>" for item in items), "</ul>", table(header, rows)]


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
    if not report.warnings:
        return ['<h2 id="warnings">Warnings</h2>', "<p>None.</p>"]
    items = []
    for warning in report.warnings:
        place = warning.file or report.config.relative
        if warning.line:
            place += f":{warning.line}" + (f":{warning.column}" if warning.column else "")
        path = f" {code(warning.path)}" if warning.path else ""
        items.append(f"<li>{code(place)}{path}: {text(warning.message)}</li>")
    return ['<h2 id="warnings">Warnings</h2>', "<ul>", *items, "</ul>"]


def render_html(report: PlanReport, at: str = "index.html", viewer_html: str = "") -> str:
    """The report as the body of the page at site path `at`; `viewer_html` (the caller's: the rest pose in the site's
    viewer) goes after the summary."""
    edges, robots = report.edges, report.robots
    configured = sum(1 for e in edges if not e.origin.kind.startswith("urdf_"))
    segments = report.output.segment_count
    lines = [
        f"<h1>Plan of {code(report.config.relative)}</h1>",
        f"<p>Root frame {code(report.root_frame)}; {plural(len(robots), 'robot')}, {plural(len(report.sources), 'source')}, "
        f"{plural(len(edges), 'edge')} ({configured:,} from the config, {len(edges) - configured:,} URDF joints), "
        f"{plural(segments, 'segment')}; {plural(len(report.warnings), 'warning')}.</p>",
        viewer_html,
        '<h2 id="pictures">Pictures</h2>',
        pictures_html(report.pictures, at, "The rest pose, drawn by the Rerun viewer."),
        *_sources(report.sources_by_name, segments > 1),
        '<h2 id="robots">Robots</h2>',
    ]
    if any(robot.joints for robot in robots):
        lines.append(f'<p class="muted">{ORDER_NOTE}</p>')
    for robot in robots:
        lines += _robot(robot, report.sample)
    lines += [
        '<h2 id="edges">Edges</h2>',
        "<p>Every edge of the frame graph, top down from the root. URDF moving joints are shown at their origin (joint "
        "value 0); the run logs their pose per row.</p>",
        table(["parent", "child", "translation (m)", "rotation (rpy deg)", "origin"], [edge_cells(e, MARKUP, text) for e in edges]),
        '<h2 id="tree">Frame tree</h2>',
        frame_tree(report.root_frame, edges),
        *_output(report.output),
        *_warnings(report),
    ]
    return "\n".join(line for line in lines if line) + "\n"

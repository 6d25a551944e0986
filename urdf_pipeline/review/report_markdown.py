"""The plan report as Markdown, for a pull-request comment: tables per source, robot and edge, the frame tree."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    pass


JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
MARKDOWN_SEGMENTS = 20  # segment rows shown in markdown; json lists them all
DASH = "—"
ORDER_NOTE = (
    "Per source value, in this order: wrap (source units) → value × unit factor × scale × sign + offset (offset in URDF "
    "units), or source_range mapped onto the joint's range → limits (clamped within the slack) → mimic joints. "
    "Limits in source units are the raw values these corrections send onto the URDF limits, low to high (as "
    "`urdf-pipeline check` and a run's limit error show them)."
)


def _n(value: float) -> str:
    return f"{value:.6g}"


def _ns(values: Sequence[float]) -> str:
    return ", ".join(_n(v) for v in values)


def _code(text: str) -> str:
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(cell.replace("|", "\\|").replace("\n", " ") for cell in cells) + " |"

    return [line(header), line(["---"] * len(header)), *(line(row) for row in rows)]


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def _source_details(source: dict[str, Any]) -> str:
    parts = []
    for key in sorted(source):
        if key in ("name", "kind", "path", "root", "names"):
            continue
        value = source[key]
        if isinstance(value, dict):  # an index
            value = f"{value['column']} ({value['kind']}{', ' + value['unit'] if value['unit'] else ''})"
        elif isinstance(value, bool):
            value = "yes" if value else "no"
        elif value is None:
            value = "row_index (generated)" if key == "index" else DASH
        parts.append(f"{key}: {value}")
    return "; ".join(parts)


def _map_cell(row: dict[str, Any]) -> str:
    parts = []
    if row["wrap"] is not None:
        parts.append(f"wrap {_n(row['wrap']['period'])} around {_n(row['wrap']['center'])}")
    if row["source_range"] is not None:
        parts.append(f"source_range [{_ns(row['source_range'])}] → [{_ns(row['target_range'])}]")
    elif row["scale"] is not None and row["scale"] != 1:
        parts.append(f"× {_n(row['scale'])}")
    return "; ".join(parts) or DASH


def _limits_cell(row: dict[str, Any]) -> str:
    if row["kind"] != "mapped":
        return DASH
    if row["limits_source_units"] is None:
        return "none"
    low, high = row["limits_source_units"]
    slack = row["slack_source_units"]
    return f"{_n(low)} .. {_n(high)}" + (f" ± {_n(slack)}" if slack else "")


def _driver_cell(row: dict[str, Any]) -> str:
    if row["kind"] == "held":
        return f"`hold = {_n(row['hold'])}`"
    if row["kind"] == "mimic":
        mimic = row["mimic"]
        return f"{_code(mimic['driver'])} × {_n(mimic['multiplier'])} + {_n(mimic['offset'])}"
    return DASH


def _observed_cell(observed: dict[str, Any] | None) -> str:
    if observed is None:
        return DASH
    if observed["min"] is None:
        return f"no finite values in {observed['rows']} rows"
    if observed["verdict"] == "no limits":
        status = "no limits"
    elif not observed["fits"]:
        status = "**outside the limits**"
    elif observed["slack_rows"]:
        status = f"fits; {observed['slack_rows']} rows within the slack"
    else:
        status = "fits"
    return f"{_n(observed['min'])} .. {_n(observed['max'])} ({status})"


def _robot_markdown(robot: dict[str, Any], sample: dict[str, Any] | None) -> list[str]:
    counts = robot["joint_counts"]
    prefix = _code(robot["frame_prefix"]) if robot["frame_prefix"] else "none"
    lines = [
        f"#### Robot {_code(robot['key'])}: URDF {_code(robot['robot_name'])}",
        "",
        f"- URDF: {_code(robot['urdf']['origin'])}, sha256 {_code(robot['urdf']['sha256'])}",
        f"- entity path {_code(robot['entity_path_prefix'])}, frame prefix {prefix}, root frame {_code(robot['root_frame'])}, "
        f"collision geometries {'kept' if robot['collision_geometries'] == 'keep' else 'dropped'}",
        "- URDF joints: " + ", ".join(f"{counts[kind]} {kind}" for kind in JOINT_TYPES) + f"; {counts['mimic']} mimic",
    ]
    if robot["source"] is None:
        return [*lines, "- a scene: no moving joints, no joint source (static transforms only)", ""]
    lines.append(
        f"- joints from source {_code(robot['source'])}; NaN policy {_code(robot['nan_policy'])}; "
        f"values beyond the slack: {_code(robot['on_violation'])}"
    )
    ignored = robot["ignored_source_values"]
    lines.append("- ignored source values: " + (", ".join(_code(name) for name in ignored) if ignored else "none"))
    if sample is not None:
        read = sample["read"].get(robot["source"], 0)
        lines.append(f"- sampled: the first {_plural(read, 'row')} of source {_code(robot['source'])} (at most {sample['rows']})")
    header = [
        "source name", "URDF joint", "type", "unit", "sign", "offset (URDF units)", "scale / range map", "limits (source units)", "mimic driver / hold",
    ]  # fmt: skip
    if sample is not None:
        header.append("observed (source units)")
    rows = []
    for row in robot["joints"]:
        cells = [
            _code(row["source_name"]) if row["source_name"] is not None else DASH,
            _code(row["joint"]),
            row["type"],
            row["unit"] or DASH,
            _n(row["sign"]) if row["sign"] is not None else DASH,
            _n(row["offset"]) if row["offset"] is not None else DASH,
            _map_cell(row),
            _limits_cell(row),
            _driver_cell(row),
        ]
        if sample is not None:
            cells.append(_observed_cell(row["observed"]))
        rows.append(cells)
    return [*lines, "", *_table(header, rows), ""]


def _edge_cells(edge: dict[str, Any]) -> list[str]:
    temporal = edge["temporal"]
    if temporal is not None:
        translation = "per row: " + ", ".join(_code(n) for n in temporal["translation_names"])
        rotation = "per row: quaternion_xyzw " + ", ".join(_code(n) for n in temporal["quaternion_xyzw_names"])
    else:
        translation, rotation = _ns(edge["translation_m"]), _ns(edge["rotation_rpy_deg"])
    return [_code(edge["parent"]), _code(edge["child"]), translation, rotation, edge["origin"]["description"]]


def _output_markdown(output: dict[str, Any]) -> list[str]:
    lines = ["#### Output", "", f"- layout {_code(output['layout'])}, application_id {_code(output['application_id'])}"]
    if output["model"] is not None:
        lines.append(f"- model (meshes, static URDF transforms, written once, static only): {_code(output['model'])}")
    if output["manifest"] is not None:
        lines.append(f"- manifest: {_code(output['manifest'])}")
    what = "layer (forward kinematics, calibration edges)" if output["layout"] == "split" else "recording"
    lines.append(f"- {_plural(output['segment_count'], 'segment')}, each a {what} whose recording_id is the segment id:")
    rows = []
    for segment in output["segments"][:MARKDOWN_SEGMENTS]:
        source = f"episode {segment['episode']}" if segment["episode"] is not None else ""
        if segment["stem"] is not None:
            source = f"file {segment['stem']}" + (f" ({source})" if source else "")
        frames = str(segment["frames"]) if segment["frames"] is not None else DASH
        rows.append([_code(segment["id"]), source or DASH, frames, _code(segment["output"])])
    hidden = output["segment_count"] - len(rows)
    if hidden > 0:
        rows.append([f"… {hidden} more", "", "", ""])
    return [*lines, "", *_table(["segment", "input", "frames", "output"], rows), ""]


def render_markdown(report: dict[str, Any]) -> str:
    edges, robots, sources = report["edges"], report["robots"], report["sources"]
    configured = sum(1 for e in edges if not e["origin"]["kind"].startswith("urdf_"))
    segments = report["output"]["segment_count"]
    lines = [
        f"### urdf-pipeline plan: {_code(report['config'])}",
        "",
        f"Root frame {_code(report['root_frame'])}; {_plural(len(robots), 'robot')}, {_plural(len(sources), 'source')}, "
        f"{_plural(len(edges), 'edge')} ({configured} from the config, {len(edges) - configured} URDF joints), "
        f"{_plural(segments, 'segment')}.",
        "",
        "#### Sources" + (" (the first segment's)" if segments > 1 else ""),
        "",
        *_table(
            ["source", "kind", "file", "reads", "values"],
            [
                [_code(s["name"]), s["kind"], _code(s.get("path", s.get("root", ""))), _source_details(s), str(len(s["names"]))]
                for s in sources
            ],
        ),
        "",
    ]
    if any(robot["joints"] for robot in robots):
        lines += [f"> {ORDER_NOTE}", ""]
    for robot in robots:
        lines += _robot_markdown(robot, report["sample"])
    lines += [
        "#### Edges",
        "",
        "Every edge of the frame graph, top down from the root. URDF moving joints are shown at their origin (joint value 0); "
        "the run logs their pose per row.",
        "",
        *_table(["parent", "child", "translation (m)", "rotation (rpy deg)", "origin"], [_edge_cells(e) for e in edges]),
        "",
        "#### Frame tree",
        "",
        "```mermaid",
        report["frame_tree"]["mermaid"],
        "```",
        "",
        "`-->` URDF moving joint, `-.->` URDF fixed joint, `==>` an edge of the config (`-.->` when its identity is assumed).",
        "",
        *_output_markdown(report["output"]),
        "#### Warnings",
        "",
    ]
    warnings = report["warnings"]
    if not warnings:
        lines.append("None.")
    for warning in warnings:
        place = warning["file"] or report["config"]
        if warning["line"]:
            place += f":{warning['line']}" + (f":{warning['column']}" if warning["column"] else "")
        lines.append(f"- {_code(place)}" + (f" {_code(warning['path'])}" if warning["path"] else "") + f": {warning['message']}")
    return "\n".join(lines) + "\n"

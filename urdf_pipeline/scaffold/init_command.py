"""`urdf-pipeline init`: scaffold a config from a URDF (any form `run` accepts: init_urdf.py), optionally pre-matched to
a source's names (source_probe.py, name_match.py); what it writes: docs/commands.md#init.

The YAML text is generated here, not dumped, so that every guess carries its reason in a comment: `# TODO: ...` what
init could not know (a stub to fill in, a decision to make), `# review: ...` a guess to check. `validate` refuses the
result only on stubs marked TODO. The text is deterministic for a given URDF, source and output location.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

import yaml

from ..config import SCHEMA_RESOURCE, Document, parse_document, schema_text
from ..confine import os_cause
from ..errors import UserError
from ..sources import SourceDescription
from ..urdf import UrdfModel
from .init_joints import Source, drivable, joints_block
from .init_messages import SampleVerdict, Scaffold, compiled, summary_lines
from .init_units import SampledUnits
from .init_urdf import InitUrdf, UrdfArgument, load_robot, package_paths
from .name_match import Match, match_names
from .source_probe import SourceInfo, read_source, stub_source
from .yaml_writer import Block, Item, Seq, render_block, to_data

IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
SCHEMA_IN_REPO = Path("schemas") / SCHEMA_RESOURCE


def _identifier(text: str, fallback: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_")
    if not cleaned:
        return fallback
    return cleaned if IDENTIFIER.match(cleaned) else f"_{cleaned}"


# ---------------------------------------------------------------------------------------------------------------
# The config


def schema_reference(out_dir: Path) -> str:
    """Relative path to the nearest schemas/urdf-pipeline.schema.json above the output, else the schema's `$id` URL
    (never a path into this installation: the config must work on another machine)."""
    real = Path(os.path.realpath(out_dir))
    for folder in (real, *real.parents):
        if (folder / SCHEMA_IN_REPO).is_file():
            return Path(os.path.relpath(folder / SCHEMA_IN_REPO, real)).as_posix()
    return str(json.loads(schema_text())["$id"])


def write_schema(target: Path) -> None:
    """`urdf-pipeline schema -o FILE`: the schema vendored where `schema_reference` finds it."""
    write_whole(target, schema_text(), "the schema")


def write_whole(target: Path, text: str, what: str) -> None:
    """`text` written whole or not at all (a temporary file beside it, then renamed), its folders created; what the OS
    refuses (a file where a folder goes, no permission) is a user error naming the path."""
    partial = target.with_name(f".{target.name}.{os.getpid()}.partial")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(text, encoding="utf-8")
        partial.replace(target)
    except OSError as exc:
        with contextlib.suppress(OSError):
            partial.unlink(missing_ok=True)
        raise UserError(f"cannot write {what} to {target}: {os_cause(exc, target)}") from None


def _pair(source: SourceDescription, joint_names: list[str]) -> tuple[list[str], list[Match]]:
    """The source's names and their pre-matched joints. Positional sources (no names) are named after the joints, in
    URDF order (extra values `value_K`); named ones are matched by name, or by position (score 0) if nothing resembles."""
    if source.names is None:
        width = source.width if source.width is not None else len(joint_names)
        names = [joint_names[i] if i < len(joint_names) else f"value_{i}" for i in range(width)]
        return names, [Match(joint_names[i], joint_names[i], 1.0) for i in range(min(width, len(joint_names)))]
    names = list(source.names)
    matches = match_names(names, joint_names)
    if source.urdf_order:  # names in any order per row: the map follows the URDF's order
        matches.sort(key=lambda m: joint_names.index(m.joint))
    if not matches:  # the map may not be empty; every entry says it is a guess by position
        matches = [Match(names[i], joint_names[i], 0.0) for i in range(min(len(names), len(joint_names)))]
    return names, matches


def _width_mismatch(source: SourceDescription, joint_names: list[str], source_key: str, robot_key: str, model: str) -> str:
    """What differs when a source without names is not as wide as the URDF has joints to drive ("" when it is): the
    names init gave by position are then surely wrong in part."""
    width, count = source.width, len(joint_names)
    if source.names is not None or width is None or width == count:
        return ""
    if width > count:
        extra = f"value_{count}" if width == count + 1 else f"value_{count} .. value_{width - 1}"
        guess = f"named the first {count} after the URDF's joints, in its order, and ignores the other {width - count} ({extra})"
    else:
        held = ", ".join(joint_names[width:])
        guess = f"named them after the URDF's first {width} joints, in its order, and holds the other {count - width} ({held})"
    return (
        f"sources.{source_key}: {width} values per row, but URDF '{model}' has {count} joints to drive; init {guess}: "
        f"edit sources.{source_key}.names to say what each value is, in order, then robots.{robot_key}.joints (map, "
        "ignore, hold) to match"
    )


def _source_entry(info: SourceInfo, names: list[str], stub: bool, mismatch: bool) -> Block:
    """The config entry: the kind's key and path, the keys its description proposes, the names when it has none."""
    source = info.description
    entry = Block()
    entry.add(source.kind, info.path, info.path_comment)
    for field in source.fields:
        entry.add(field.key, field.value, field.comment)
    if source.names is None:
        why = source.unnamed
        if stub:
            comment = "the URDF's joints; TODO: the names of your values, in their order (then map each below)"
        elif source.width is None:
            comment = f"review: {why} and the column's width is not fixed: assumed one value per URDF joint, in URDF order"
        elif mismatch:
            comment = f"TODO: {why}, and its {source.width} values are not one per URDF joint: named by position, say what each is"
        else:
            comment = f"review: {why}: assumed the values come in the URDF's joint order"
        entry.add("names", names, comment)
    for note in source.notes:
        entry.note(note)
    return entry


@dataclass(frozen=True)
class ScaffoldInputs:
    """What init reads once: the robot (xacro expanded) and the source's description."""

    description: InitUrdf
    info: SourceInfo
    source: str | None
    out_file: Path
    key: str  # the robot's key in the config (_robot_key)

    @property
    def source_key(self) -> str:
        return f"{self.key}_state"


def _robot_key(description: InitUrdf) -> str:
    """The robot's key in the config: its URDF name, else its file's, as a YAML-safe identifier."""
    return _identifier(description.model.name, _identifier(description.file.stem.split(".")[0], "robot"))


def load_inputs(urdf: UrdfArgument, source: str | None, out_file: Path) -> ScaffoldInputs:
    description = load_robot(urdf, out_file)
    joint_names = [j.name for j in drivable(description.model)]
    key = _robot_key(description)
    info = stub_source(key, joint_names) if source is None else read_source(source, f"{key}_state", out_file)
    return ScaffoldInputs(description, info, source, out_file, key)


def compose(inputs: ScaffoldInputs, units: SampledUnits | None = None) -> Scaffold:
    """The config in the order a reader fills it in: the source, the robot, its place in the scene, the output."""
    names, matches, mismatch = _paired(inputs)
    config = Block()
    config.add("version", 1)
    config.add("sources", _sources(inputs, names, bool(mismatch)))
    config.add("robots", _robots(inputs, names, matches, units))
    frames, edges = _scene(inputs.description.model)
    config.add("frames", frames)
    if edges is not None:
        config.add("edges", edges, "calibration: where the robot stands in the scene")
    config.add("output", _output(inputs))
    return _rendered(inputs, config, matches, mismatch)


def _paired(inputs: ScaffoldInputs) -> tuple[list[str], list[Match], str]:
    """The source's names, the joints they match, what differs in width (a source without names); no values: refused."""
    model, source = inputs.description.model, inputs.info.description
    joint_names = [j.name for j in drivable(model)]
    names, matches = _pair(source, joint_names)
    if not matches:
        raise UserError(f"--source {inputs.source}: it holds no values")
    return names, matches, _width_mismatch(source, joint_names, inputs.source_key, inputs.key, model.name)


def _sources(inputs: ScaffoldInputs, names: list[str], mismatch: bool) -> Block:
    """`sources:`, the one source: the stub to fill in, or the entry proposed from --source's metadata."""
    stub = inputs.source is None
    entry = _source_entry(inputs.info, names, stub, mismatch)
    sources = Block()
    sources.add(inputs.source_key, entry, "TODO: where the joint values come from" if stub else f"from --source {inputs.source}")
    return sources


def _robots(inputs: ScaffoldInputs, names: list[str], matches: list[Match], units: SampledUnits | None) -> Block:
    """`robots:`, the one robot: its URDF in the form given, the package folders its meshes need, its joints."""
    description, model = inputs.description, inputs.description.model
    robot = Block()
    robot.add("urdf", description.entry, f"{model.name}: {len(drivable(model))} joints to drive, {len(model.links)} links")
    paths = package_paths(description, inputs.out_file.parent)
    if paths is not None:
        stubbed = any("TODO" in i.comment for i in paths.items if isinstance(i, Item))
        robot.add("package_paths", paths, "TODO: meshes that do not resolve until the stubs below are filled in" if stubbed else "")
    source_spec = Source(inputs.source_key, inputs.info.description, inputs.source is None)
    robot.add("joints", joints_block(inputs.description.model, source_spec, names, matches, units))
    robots = Block()
    robots.add(inputs.key, robot)
    return robots


def _scene(model: UrdfModel) -> tuple[Block, Seq | None]:
    """`frames:`, and the calibration edge from the scene's root to the URDF's root link (None: that link is the root)."""
    root = "world" if "world" not in model.links or model.root_link == "world" else "scene"  # a URDF link 'world' below its root
    frames = Block()
    frames.add("root", root, "the one root frame of the scene")
    if model.root_link == root:
        frames.note(f"the URDF's root link is '{root}' itself: no calibration edge needed")
        return frames, None
    edge = Block()
    edge.add("parent", root)
    edge.add("child", model.root_link, "the URDF's root link")
    edge.add("translation", [0.0, 0.0, 0.0], "TODO: measure (m)")
    edge.add("quaternion_xyzw", [0.0, 0.0, 0.0, 1.0], "TODO: measure (or rpy / rpy_deg)")
    return frames, Seq([(edge, "")])


def _output(inputs: ScaffoldInputs) -> Block:
    """`output:`, the recording's path, application id and segment id (the source's proposal, so layers can attach)."""
    output = Block()
    output.add("path", "out/{segment}.rrd")
    output.add("application_id", inputs.key)
    output.add("segment", inputs.info.description.segment, "the recording id (layers attach only when it equals the base recording's)")
    return output


def _rendered(inputs: ScaffoldInputs, config: Block, matches: list[Match], mismatch: str) -> Scaffold:
    """The text, a header (schema, origin, how to read the marks) then the config, and its counts for init's summary."""
    header = [
        f"# yaml-language-server: $schema={schema_reference(inputs.out_file.parent)}",
        f"# Generated by `urdf-pipeline init` from {inputs.description.shown}" + (f" and {inputs.source}." if inputs.source else "."),
        "# `TODO:` marks what init could not know (a stub to fill in, a decision to make); `review:` a guess to check.",
        "# Then `urdf-pipeline check` compares the data with the URDF limits and suggests unit and sign corrections.",
    ]
    body = render_block(config)
    data = to_data(config)
    return Scaffold(
        text="\n".join(header + body) + "\n",
        data=data,
        stub=inputs.source is None,
        mapped=len(matches),
        by_name=0 if inputs.source is None or inputs.info.description.names is None else sum(m.score > 0 for m in matches),
        held=len(data["robots"][inputs.key]["joints"].get("hold", {})),
        ignored=len(data["robots"][inputs.key]["joints"].get("ignore", [])),
        todos=sum("# TODO" in line for line in body),
        mismatch=mismatch,
    )


def self_check(result: Scaffold, out_file: Path) -> Document:
    """The text must read back as the intended data and satisfy the schema: anything else is a bug of init's."""
    from ..config import validate_document

    document = parse_document(result.text, out_file)
    if yaml.safe_load(result.text) != result.data:
        raise AssertionError("init: the generated YAML does not read back as intended:\n" + result.text)
    try:
        validate_document(document)
    except UserError as exc:
        raise AssertionError("init: the generated config fails the schema: " + "; ".join(exc.lines())) from None
    return document


def init_config(urdf: UrdfArgument, source: str | None, output: Path | None, force: bool) -> tuple[Scaffold, list[str]]:
    """Scaffold, check and write (to `output`, or return it for stdout); the lines to say on stderr. With a source,
    a bounded sample (check's) chooses each joint's unit, and check's rules judge the result (init_units.py)."""
    from .init_units import read_units, refused_by_check

    out_file = (output if output is not None else Path.cwd() / "urdf-pipeline.yaml").absolute()
    if output is not None and out_file.exists() and not force:
        raise UserError(f"{output} exists; --force overwrites it")
    inputs = load_inputs(urdf, source, out_file)
    result = compose(inputs)
    plan, problems = compiled(self_check(result, out_file))
    verdict = None
    if plan is not None and source is not None:
        units, sample, unread = read_units(plan)
        if units is not None and units.joints:
            result = compose(inputs, units)
            plan, problems = compiled(self_check(result, out_file))
        refused = tuple(refused_by_check(plan, sample)) if plan is not None and units is not None else ()
        verdict = SampleVerdict(refused, unread, units.rows if units is not None else 0)
    if output is not None:
        write_whole(out_file, result.text, "the config")
    return result, summary_lines(result, problems, output, verdict)

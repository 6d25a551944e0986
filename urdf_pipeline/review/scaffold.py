"""`urdf-pipeline init`: scaffold a config from a URDF, optionally pre-matched to a source's names.

The result is YAML text with comments, generated here (not dumped) so that every guess carries its reason:
`# TODO: ...` marks what init could not know (a stub to fill in, a decision to make: an ignored name, a held joint,
the calibration edge), `# review: ...` a guess to check (a name match and its score, a unit). `validate` refuses
the result only on stubs that cannot work as they are, all marked TODO: the stub source file (which does not exist),
a package folder init could not find. The text is deterministic for a given URDF, source and output location.

SOURCE_SPEC is `KIND:PATH[#PART]` (PATH relative to the current directory): each kind in `sources.KINDS` says its
form (`SPEC_FORM`, e.g. `parquet:FILE[#COLUMN]`), what PART defaults to, and describes the source (`describe`) from
its metadata only, as `validate` reads it, never joint values. `KIND:` may be left out when the path says it (the
kinds' `SUFFIXES`, a directory holding meta/info.json). A glob in a file path (`data/*.parquet`) becomes a globbed
source, one segment per file. `source_probe.py` turns the description into the config entry.

Sources with names are matched to the URDF's joints by name similarity (see `match_names`); sources without names
(parquet, HDF5, a LeRobot feature without names) are matched by position and get the URDF joint names as `names`.

The `# yaml-language-server: $schema=...` line points at the nearest `schemas/urdf-pipeline.schema.json` found in the
output's folder or one of its parents (this repository's, or a copy vendored in the user's repository), as a relative
path; otherwise at the schema installed with the package, as an absolute path.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import yaml

from ..config import SCHEMA_RESOURCE, Document, parse_document
from ..errors import UserError
from ..sources import SourceDescription
from ..urdf import Joint, UrdfModel, UrdfParseError, package_roots, read_urdf
from .name_match import Match, match_names
from .source_probe import SourceInfo, _relative, read_source, stub_source
from .yaml_writer import Block, Item, Seq, number, render_block, to_data

IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
SCHEMA_IN_REPO = Path("schemas") / SCHEMA_RESOURCE


# ---------------------------------------------------------------------------------------------------------------
# The URDF side: package paths, joint descriptions


def _package_uris(model: UrdfModel) -> dict[str, list[str]]:
    """package NAME -> the rest of each of its mesh URIs, in URDF order."""
    found: dict[str, list[str]] = {}
    for mesh in model.meshes:
        if mesh.uri.startswith("package://"):
            package, _, rest = mesh.uri[len("package://") :].partition("/")
            rests = found.setdefault(package, [])
            if rest not in rests:
                rests.append(rest)
    return found


def _package_candidates(package: str, urdf: Path) -> list[tuple[Path, str]]:
    """Where package NAME may be: an ancestor named NAME, NAME (or share/NAME, NAME/share/NAME) beside an ancestor,
    then ROS_PACKAGE_PATH / AMENT_PREFIX_PATH."""
    chains = []
    for folder in (Path(os.path.abspath(urdf)).parent, Path(os.path.realpath(urdf)).parent):
        chains.append([folder, *folder.parents])
    found: list[tuple[Path, str]] = []
    for chain in chains:
        found += [(a, "an ancestor folder of the URDF") for a in chain if a.name == package]
    for chain in chains:
        for ancestor in chain:
            for candidate in (ancestor / package, ancestor / "share" / package, ancestor / package / "share" / package):
                found.append((candidate, "found beside the URDF"))
    found += [(root, "from ROS_PACKAGE_PATH / AMENT_PREFIX_PATH") for root in package_roots(package)]
    seen: set[str] = set()
    unique = []
    for path, why in found:
        if str(path) not in seen and path.is_dir():
            seen.add(str(path))
            unique.append((path, why))
    return unique


def resolve_package(package: str, rests: list[str], urdf: Path) -> tuple[Path, str, int] | None:
    """The folder holding most of the package's meshes (all, ideally): (folder, why, meshes found there)."""
    best: tuple[Path, str, int] | None = None
    for folder, why in _package_candidates(package, urdf):
        count = sum((folder / unquote(rest)).is_file() for rest in rests)
        if count and (best is None or count > best[2]):
            best = (folder, why, count)
        if count == len(rests):
            break
    return best


def joint_summary(joint: Joint) -> str:
    unit = "rad" if joint.angular else "m"
    if joint.type == "continuous":
        return "continuous, no limits (rad)"
    if joint.has_limits:
        return f"{joint.type}, {number(joint.lower or 0.0)} .. {number(joint.upper or 0.0)} {unit}"
    return f"{joint.type}, no usable limits ({unit})"


def hold_value(joint: Joint) -> float:
    """0.0, or the middle of the limits when 0 is outside them."""
    if not joint.has_limits or (joint.lower or 0.0) <= 0.0 <= (joint.upper or 0.0):
        return 0.0
    lower, upper = float(joint.lower or 0.0), float(joint.upper or 0.0)
    middle = round((lower + upper) / 2, 6)
    return middle if lower <= middle <= upper else (lower + upper) / 2


def _identifier(text: str, fallback: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_")
    if not cleaned:
        return fallback
    return cleaned if IDENTIFIER.match(cleaned) else f"_{cleaned}"


# ---------------------------------------------------------------------------------------------------------------
# The config


def schema_reference(out_dir: Path) -> str:
    """Relative path to the nearest schemas/urdf-pipeline.schema.json above the output, else the installed schema."""
    real = Path(os.path.realpath(out_dir))
    for folder in (real, *real.parents):
        if (folder / SCHEMA_IN_REPO).is_file():
            return Path(os.path.relpath(folder / SCHEMA_IN_REPO, real)).as_posix()
    installed = resources.files("urdf_pipeline").joinpath("data", SCHEMA_RESOURCE)
    return Path(str(installed)).resolve().as_posix()


@dataclass(frozen=True)
class Scaffold:
    """The config text and what it holds, counted for the summary init prints."""

    text: str
    data: dict[str, Any]  # what the text reads back as
    stub: bool  # no --source: the stub source
    mapped: int
    by_name: int
    held: int
    ignored: int
    todos: int


def _load(urdf: Path) -> UrdfModel:
    if urdf.name.endswith(".xacro"):
        raise UserError(
            f"{urdf} is a xacro file: init reads a plain URDF (expand it with xacro first, then use the xacro form in the config)"
        )
    if not urdf.is_file():
        raise UserError(f"URDF file not found: {urdf}")
    try:
        _, model = read_urdf(urdf)
    except (UrdfParseError, OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{urdf}: {exc}") from None
    if not any(j.moving and j.mimic is None for j in model.joints):
        raise UserError(
            f"URDF '{model.name}' has no joint to drive (no revolute, continuous or prismatic joint without <mimic>); "
            "a scene URDF goes beside a robot in that robot's config, as a robot without joints"
        )
    return model


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


def _source_entry(info: SourceInfo, names: list[str], stub: bool) -> Block:
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
        else:
            comment = f"review: {why}: assumed the values come in the URDF's joint order"
        entry.add("names", names, comment)
    for note in source.notes:
        entry.note(note)
    return entry


def _package_paths(model: UrdfModel, urdf: Path, out_dir: Path) -> Block | None:
    packages = _package_uris(model)
    if not packages:
        return None
    paths = Block()
    for package, rests in sorted(packages.items()):
        resolved = resolve_package(package, rests, urdf)
        if resolved is None:
            paths.add(package, f"TODO/{package}", f"TODO: the folder package://{package}/... refers to ({len(rests)} mesh files)")
        else:
            folder, why, count = resolved
            comment = why if count == len(rests) else f"review: only {count} of its {len(rests)} mesh files are there"
            paths.add(package, _relative(folder, out_dir), comment)
    return paths


def _joints(model: UrdfModel, source_key: str, source: SourceDescription, names: list[str], matches: list[Match], stub: bool) -> Block:
    drivable = [j for j in model.joints if j.moving and j.mimic is None]
    by_name = {j.name: j for j in model.joints}
    joints = Block()
    joints.add("source", source_key)
    unit = "rad" if any(j.angular for j in drivable) else "m"
    other = "prismatic joints say theirs (m | mm) in their entry" if unit == "rad" else "all joints are prismatic"
    joints.add("unit", unit, f"review: the unit of the source values ({'rad | deg' if unit == 'rad' else 'm | mm'}); {other}")
    mapping = Block()
    for match in matches:
        joint = by_name[match.joint]
        value: Any = match.joint if joint.angular == (unit == "rad") else {"joint": match.joint, "unit": "rad" if joint.angular else "m"}
        if stub:
            comment = joint_summary(joint)
        elif source.names is None:
            comment = f"review: matched by position; {joint_summary(joint)}"
        elif match.score == 0.0:
            comment = f"TODO: no source name resembles a joint name: matched by position, surely wrong; {joint_summary(joint)}"
        else:
            comment = f"review: matched by name (score {match.score:.2f}); {joint_summary(joint)}"
        mapping.add(match.source_name, value, comment)
    joints.add("map", mapping, "source name: URDF joint (add sign, offset, unit per entry when needed)")
    matched_sources = {m.source_name for m in matches}
    unmatched = [n for n in names if n not in matched_sources]
    if unmatched:
        why = "a value beyond the URDF's joints" if source.names is None else "no URDF joint resembles it"
        joints.add("ignore", Seq([(n, f"TODO: {why}: map it, or keep it ignored") for n in unmatched]), "source names deliberately unused")
    matched_joints = {m.joint for m in matches}
    held = [j for j in drivable if j.name not in matched_joints]
    if held:
        hold = Block()
        for joint in held:
            value = hold_value(joint)
            hold.add(joint.name, value, f"TODO: not in the data, held at {number(value)}; {joint_summary(joint)}")
        joints.add("hold", hold, "URDF joints the data lacks -> a fixed value in URDF units")
    for joint in model.joints:
        if joint.mimic is not None:
            m = joint.mimic
            joints.note(
                f"mimic (computed by the pipeline, not mapped): {joint.name} = {m.joint} * {number(m.multiplier)} + {number(m.offset)}"
            )
    for joint in model.joints:
        if joint.type in ("floating", "planar"):
            joints.note(
                f"{joint.type} joint {joint.name} ({joint.parent} -> {joint.child}) is not driven: a static identity unless "
                "a temporal edge (edges: - {parent, child, source, translation, quaternion_xyzw}) drives it"
            )
    return joints


def scaffold(urdf: Path, source: str | None, out_file: Path) -> Scaffold:
    """The config text for URDF `urdf` (and source spec `source`), to be written at `out_file` (paths relative to it)."""
    model = _load(urdf)
    out_dir = out_file.parent
    key = _identifier(model.name, _identifier(urdf.stem.split(".")[0], "robot"))
    source_key = f"{key}_state"
    joint_names = [j.name for j in model.joints if j.moving and j.mimic is None]
    stub = source is None
    info = stub_source(key, joint_names) if source is None else read_source(source, source_key, out_file)
    names, matches = _pair(info.description, joint_names)
    if not matches:
        raise UserError(f"--source {source}: it holds no values")

    sources = Block()
    sources.add(
        source_key, _source_entry(info, names, stub), "TODO: where the joint values come from" if stub else f"from --source {source}"
    )
    robot = Block()
    robot.add("urdf", _relative(urdf, out_dir), f"{model.name}: {len(joint_names)} joints to drive, {len(model.links)} links")
    paths = _package_paths(model, urdf, out_dir)
    if paths is not None:
        stubbed = any("TODO" in i.comment for i in paths.items if isinstance(i, Item))
        robot.add("package_paths", paths, "TODO: meshes that do not resolve until the stubs below are filled in" if stubbed else "")
    joints = _joints(model, source_key, info.description, names, matches, stub)
    robot.add("joints", joints)
    robots = Block()
    robots.add(key, robot)

    root = "world" if "world" not in model.links or model.root_link == "world" else "scene"  # a URDF link 'world' below its root
    frames = Block()
    frames.add("root", root, "the one root frame of the scene")
    config = Block()
    config.add("version", 1)
    config.add("sources", sources)
    config.add("robots", robots)
    config.add("frames", frames)
    if model.root_link != root:
        edge = Block()
        edge.add("parent", root)
        edge.add("child", model.root_link, "the URDF's root link")
        edge.add("translation", [0.0, 0.0, 0.0], "TODO: measure (m)")
        edge.add("quaternion_xyzw", [0.0, 0.0, 0.0, 1.0], "TODO: measure (or rpy / rpy_deg)")
        config.add("edges", Seq([(edge, "")]), "calibration: where the robot stands in the scene")
    else:
        frames.note(f"the URDF's root link is '{root}' itself: no calibration edge needed")
    output = Block()
    output.add("path", "out/{segment}.rrd")
    output.add("application_id", key)
    output.add("segment", info.description.segment, "the recording id (layers attach only when it equals the base recording's)")
    config.add("output", output)

    header = [
        f"# yaml-language-server: $schema={schema_reference(out_dir)}",
        f"# Generated by `urdf-pipeline init` from {_relative(urdf, out_dir)}" + (f" and {source}." if source else "."),
        "# `TODO:` marks what init could not know (a stub to fill in, a decision to make); `review:` a guess to check.",
        "# Then `urdf-pipeline check` compares the data with the URDF limits and suggests unit and sign corrections.",
    ]
    body = render_block(config)
    data = to_data(config)
    return Scaffold(
        text="\n".join(header + body) + "\n",
        data=data,
        stub=stub,
        mapped=len(matches),
        by_name=0 if stub or info.description.names is None else sum(m.score > 0 for m in matches),
        held=len(data["robots"][key]["joints"].get("hold", {})),
        ignored=len(data["robots"][key]["joints"].get("ignore", [])),
        todos=sum("# TODO" in line for line in body),
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


def remaining_problems(document: Document) -> list[str]:
    """What `validate` would still refuse (expected: the TODO stubs), as messages without the file location."""
    from ..compile import compile_document
    from ..errors import UserErrors

    try:
        compile_document(document)
    except UserErrors as exc:
        return [f"{e.where.path}: {e.message}" if e.where and e.where.path else e.message for e in exc.errors]
    except UserError as exc:
        return [f"{exc.where.path}: {exc.message}" if exc.where and exc.where.path else exc.message]
    return []


def summary_lines(result: Scaffold, problems: list[str], output: Path | None) -> list[str]:
    """What init says on stderr, from its result and what validate would still refuse: worded here only."""
    how = f"{result.by_name} by name, for review" if result.by_name else "the stub's names" if result.stub else "by position"
    said = [
        f"init: {result.mapped} joint(s) mapped ({how}), {result.held} held, {result.ignored} source name(s) ignored; "
        f"{result.todos} TODO(s) to settle" + (f" in {output}" if output is not None else "")
    ]
    if problems:
        said.append(f"init: validate would still refuse {len(problems)} thing(s), the stubs marked TODO:")
        said += [f"  {problem}" for problem in problems]
    else:
        said.append("init: the config validates; review the guesses marked `review:` and `TODO:`")
    return said


def init_config(urdf: Path, source: str | None, output: Path | None, force: bool) -> tuple[Scaffold, list[str]]:
    """Scaffold, check and write (to `output`, or return it for stdout); the lines to say on stderr."""
    out_file = (output if output is not None else Path.cwd() / "urdf-pipeline.yaml").absolute()
    if output is not None and out_file.exists() and not force:
        raise UserError(f"{output} exists; --force overwrites it")
    result = scaffold(urdf, source, out_file)
    problems = remaining_problems(self_check(result, out_file))
    if output is not None:
        out_file.parent.mkdir(parents=True, exist_ok=True)
        partial = out_file.with_name(out_file.name + ".partial")
        partial.write_text(result.text, encoding="utf-8")
        partial.replace(out_file)
    return result, summary_lines(result, problems, output)

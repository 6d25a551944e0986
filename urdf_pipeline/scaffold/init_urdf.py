"""init's view of a robot description: the URDF forms `run` accepts, loaded by the code `run` uses
(`urdf.load_urdf_source`), each written as the matching `robots.KEY.urdf` entry, and the package folders the config's
`package_paths` need.

A xacro is expanded under the output config's confinement (what `validate` will allow) widened by the folders the
user named or init found: when xacro says it needs `$(find PKG)`, init looks for PKG as it looks for a mesh package,
expands again with it, and puts the folder into `package_paths`, as `validate` needs it there.
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal
from urllib.parse import unquote

from ..confine import confinement_for
from ..errors import UserError, Where
from ..urdf import (
    LoadedUrdf,
    UrdfModel,
    UrdfParseError,
    XacroBudget,
    XacroContent,
    load_urdf_source,
    package_roots,
    parse_urdf_text,
    read_urdf,
)
from .source_probe import relative_to
from .yaml_writer import Block

FIND_NEEDED = re.compile(r"xacro needs \$\(find ([^)\s]+)\)")  # urdf/xacro_sandbox.py's message for a package it lacks
MAX_FINDS = 32  # expansions retried with one more $(find PKG) folder each, at most

UrdfForm = Literal["urdf", "xacro", "robot_descriptions"]


@dataclass(frozen=True)
class UrdfArgument:
    """The robot as init's command line names it: a plain URDF path, a xacro path and its arguments, or a
    robot_descriptions module name. Paths are relative to the current directory."""

    form: UrdfForm
    value: str
    args: tuple[tuple[str, str], ...] = ()  # xacro arguments, in the order given

    @property
    def option(self) -> str:
        return f"--{self.form.replace('_', '-')} {self.value}"


def urdf_argument(urdf: str | None, xacro: str | None, args: Sequence[str], robot_descriptions: str | None) -> UrdfArgument:
    """init's URDF options (argparse lets exactly one form through) as one argument; a ValueError is a usage error."""
    if args and xacro is None:
        raise ValueError("--arg NAME=VALUE goes with --xacro FILE")
    if xacro is not None:
        return UrdfArgument("xacro", xacro, parse_xacro_args(args))
    if robot_descriptions is not None:
        return UrdfArgument("robot_descriptions", robot_descriptions)
    return UrdfArgument("urdf", str(urdf))


def parse_xacro_args(texts: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """`--arg NAME=VALUE` values, split at the first `=`; a ValueError says which one is malformed (a usage error)."""
    pairs: dict[str, str] = {}
    for text in texts:
        name, equals, value = text.partition("=")
        if not equals or not name.strip() or name != name.strip():
            raise ValueError(f"--arg {text!r}: the form is NAME=VALUE (xacro's NAME:=VALUE), NAME not empty")
        if name in pairs:
            raise ValueError(f"--arg {name} is given twice")
        pairs[name] = value
    return tuple(pairs.items())


@dataclass(frozen=True)
class InitUrdf:
    """A robot's description as loaded for init, and how the config names it."""

    model: UrdfModel
    file: Path  # the file the text came from: relative mesh paths and package folders are looked for from it
    entry: Any  # the config's robots.KEY.urdf value
    shown: str  # what init says it read ("xacro robots/arm.urdf.xacro robot_name:=vx300s")
    provided: Mapping[str, Path] = field(default_factory=dict)  # package roots the form itself gives
    finds: Mapping[str, Path] = field(default_factory=dict)  # the folders init found for the xacro's $(find PKG)


def load_robot(argument: UrdfArgument, out_file: Path) -> InitUrdf:
    """The robot `argument` names, for a config to be written at `out_file`; a UserError names the option at fault."""
    if argument.form == "xacro":
        robot = _xacro(argument, out_file)
    elif argument.form == "robot_descriptions":
        robot = _robot_descriptions(argument, out_file)
    else:
        robot = _plain(argument, out_file)
    if not any(j.moving and j.mimic is None for j in robot.model.joints):
        raise UserError(
            f"URDF '{robot.model.name}' has no joint to drive (no revolute, continuous or prismatic joint without <mimic>); "
            "a scene URDF goes beside a robot in that robot's config, as a robot without joints"
        )
    return robot


def _plain(argument: UrdfArgument, out_file: Path) -> InitUrdf:
    urdf = Path(argument.value)
    if urdf.name.endswith(".xacro"):
        raise UserError(f"{urdf} is a xacro file: use --xacro {argument.value} (and --arg NAME=VALUE for its arguments)")
    if not urdf.is_file():
        raise UserError(f"URDF file not found: {urdf}")
    try:
        _, model = read_urdf(urdf)
    except XacroContent as exc:
        raise UserError(
            exc.advice(f"use --xacro {argument.value} (and --arg NAME=VALUE for its arguments); a config names it urdf: {{xacro: FILE}}")
        ) from None
    except (UrdfParseError, OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{urdf}: {exc}") from None
    relative = relative_to(urdf, out_file.parent)
    return InitUrdf(model, urdf, relative, relative)


def _xacro(argument: UrdfArgument, out_file: Path) -> InitUrdf:
    """Expanded as `validate` expands it; each `$(find PKG)` xacro asks for and init finds is given, and it expands again."""
    path = Path(argument.value)
    if not path.is_file():
        raise UserError(f"{argument.option}: xacro file not found")
    relative = relative_to(path, out_file.parent)
    entry: dict[str, Any] = {"xacro": relative}
    if argument.args:
        entry["args"] = dict(argument.args)
    base = confinement_for(out_file)
    finds: dict[str, Path] = {}
    budget = XacroBudget("init's")  # one for every expansion below: a retry takes its time from the same bound
    while True:
        roots = (path.parent.resolve(), *(folder.resolve() for folder in finds.values()))
        confinement = dataclasses.replace(base, read_roots=(*base.read_roots, *roots))
        try:
            loaded = load_urdf_source(entry, finds, out_file.parent, confinement, Where(path, 0), budget)
            break
        except UserError as exc:
            needed = FIND_NEEDED.search(exc.message)
            if needed is None or needed[1] in finds or len(finds) >= MAX_FINDS:
                raise UserError(f"{argument.option}: {exc.message}") from None
            package = needed[1]
            found = _package_candidates(package, path)
            if not found:
                raise UserError(
                    f"{argument.option}: the xacro needs $(find {package}) and init found no folder {package} above or beside "
                    f"it, nor on ROS_PACKAGE_PATH / AMENT_PREFIX_PATH: put the folder holding {package} on ROS_PACKAGE_PATH "
                    "and run init again"
                ) from None
            finds[package] = found[0][0]
    shown = " ".join([f"xacro {relative}", *(f"{name}:={value}" for name, value in argument.args)])
    return InitUrdf(_model(loaded, argument, source_lines=False), path, entry, shown, {}, finds)


def _robot_descriptions(argument: UrdfArgument, out_file: Path) -> InitUrdf:
    entry = {"robot_descriptions": argument.value}
    try:
        loaded = load_urdf_source(entry, {}, out_file.parent, confinement_for(out_file), Where(Path(argument.value), 0))
    except UserError as exc:
        raise UserError(f"{argument.option}: {exc.message}") from None
    model = _model(loaded, argument, source_lines=True)
    return InitUrdf(model, loaded.path, entry, f"robot_descriptions {argument.value}", dict(loaded.package_paths))


def _model(loaded: LoadedUrdf, argument: UrdfArgument, source_lines: bool) -> UrdfModel:
    try:
        return parse_urdf_text(loaded.text, str(loaded.path), source_lines)
    except XacroContent as exc:
        if argument.form == "xacro":
            raise UserError(f"{argument.option}: the expansion still holds xacro ({exc.found}): xacro left it unexpanded") from None
        fix = f"expand it with init --xacro {loaded.path}; a config names it urdf: {{xacro: FILE}}"
        raise UserError(f"{argument.option}: {exc.advice(fix, what='the file it gives')}") from None
    except UrdfParseError as exc:
        raise UserError(f"{argument.option}: {exc}") from None


# ---------------------------------------------------------------------------------------------------------------
# Package folders


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
    chains = [[folder, *folder.parents] for folder in (Path(os.path.abspath(urdf)).parent, Path(os.path.realpath(urdf)).parent)]
    found: list[tuple[Path, str]] = []
    for chain in chains:
        found += [(a, "an ancestor folder of the URDF") for a in chain if a.name == package]
    for chain in chains:
        for ancestor in chain:
            for candidate in (ancestor / package, ancestor / "share" / package, ancestor / package / "share" / package):
                found.append((candidate, "found beside the URDF"))
    found += [(root, "from ROS_PACKAGE_PATH / AMENT_PREFIX_PATH") for root in package_roots(package)]
    unique: dict[Path, str] = {}  # each folder once, with the first reason found
    for path, why in found:
        if path not in unique and path.is_dir():
            unique[path] = why
    return list(unique.items())


def _count(folder: Path, rests: list[str]) -> int:
    return sum((folder / unquote(rest)).is_file() for rest in rests)


def resolve_package(package: str, rests: list[str], urdf: Path) -> tuple[Path, str, int] | None:
    """The folder holding most of the package's meshes (all, ideally): (folder, why, meshes found there)."""
    best: tuple[Path, str, int] | None = None
    for folder, why in _package_candidates(package, urdf):
        count = _count(folder, rests)
        if count and (best is None or count > best[2]):
            best = (folder, why, count)
        if count == len(rests):
            break
    return best


def package_paths(robot: InitUrdf, out_dir: Path) -> Block | None:
    """The config's package_paths: the xacro's $(find PKG) folders and the mesh packages' folders, found or stubbed
    (`TODO/PKG`); none for a package the form provides with all its meshes."""
    uris = _package_uris(robot.model)
    paths = Block()
    for package in sorted(set(uris) | set(robot.finds)):
        rests = uris.get(package, [])
        provided = robot.provided.get(package)
        if package not in robot.finds and provided is not None and _count(provided, rests) == len(rests):
            continue  # robot_descriptions gives it
        if package in robot.finds:
            folder, count = robot.finds[package], _count(robot.finds[package], rests)
            short = f"; review: only {count} of its {len(rests)} mesh files are there" if count < len(rests) else ""
            paths.add(package, relative_to(folder, out_dir), f"$(find {package}) in the xacro{short}")
            continue
        resolved = resolve_package(package, rests, robot.file)
        if resolved is None:
            paths.add(package, f"TODO/{package}", f"TODO: the folder package://{package}/... refers to ({len(rests)} mesh files)")
        else:
            folder, why, count = resolved
            comment = why if count == len(rests) else f"review: only {count} of its {len(rests)} mesh files are there"
            paths.add(package, relative_to(folder, out_dir), comment)
    return paths if paths.items else None

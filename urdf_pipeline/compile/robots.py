"""Compile one robot: load its URDF, resolve every mesh, map its joints."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..confine import Confinement, Unresolvable, resolved
from ..errors import UserError, UserErrors, Where, listing, warn
from ..plan import RobotPlan
from ..urdf import (
    LoadedUrdf,
    UrdfModel,
    UrdfParseError,
    XacroContent,
    garbage_meshes,
    load_urdf_source,
    parse_urdf,
    parse_urdf_text,
    rerun_depth_problem,
    rerun_loader_error,
    resolve_meshes,
    rewrite_mesh_uris,
    text_for_rerun,
)
from .context import CompileContext, SourceNames
from .joint_mapping import JointMapping, compile_joints


@dataclass(frozen=True)
class RobotUrdf:
    """A robot's URDF as loaded, its model and the text Rerun's loader gets (the model is read from that text)."""

    loaded: LoadedUrdf
    model: UrdfModel
    rerun_text: str


@dataclass(frozen=True)
class CompiledRobot:
    """A robot's plan and its parsed URDF, kept for the edges that walk it (fixed_chain)."""

    plan: RobotPlan
    model: UrdfModel


def _xacro_refusal(exc: XacroContent, urdf: Any, loaded: LoadedUrdf) -> str:
    """A xacro text given as URDF, with the fix of the form that gave it."""
    if isinstance(urdf, str):
        return exc.advice(f"expand it as xacro: urdf: {{xacro: {urdf}}} (with args: {{NAME: VALUE}} for its arguments)")
    if "xacro" in urdf:
        return f"the expansion of {urdf['xacro']} still holds xacro ({exc.found}, line {exc.line} of the expanded text): xacro left it unexpanded"
    return exc.advice(
        f"expand it as xacro: urdf: {{xacro: {loaded.path}}} with package_paths for the packages it names",
        what=f"robot_descriptions '{urdf['robot_descriptions']}' gives a file that",
    )


def _check_depth(model: UrdfModel, loaded: LoadedUrdf, where: Where) -> None:
    """A tree deeper than Rerun's loader can walk would crash `run` (a stack overflow, no message): refused here."""
    depth, deepest = model.depth()
    problem = rerun_depth_problem(depth)
    if problem is not None:
        message = f"{loaded.path.name} is a tree {depth:,} joints deep (link '{deepest}' below root link '{model.root_link}'); {problem}"
        raise UserError(message, where)


def load_urdf(ctx: CompileContext, key: str, spec: dict[str, Any], package_paths: dict[str, Path]) -> RobotUrdf:
    """The loaded URDF, its model and the text for Rerun's loader (axes normalised, what Rerun refuses repaired, with a
    warning saying what); the model is read from that text, so a visual dropped there needs no mesh."""
    where = ctx.where("robots", key, "urdf")
    loaded = load_urdf_source(spec["urdf"], package_paths, ctx.config_dir, ctx.confinement, where, ctx.xacro_budget)
    try:
        is_file = isinstance(spec["urdf"], str) or "xacro" not in spec["urdf"]  # an expanded xacro has no lines to point at
        model, root = parse_urdf(loaded.text, str(loaded.path), source_lines=is_file)
        text, notes = text_for_rerun(loaded.text, str(loaded.path), root)
        if text is not loaded.text:  # repaired: the model is read from what Rerun will draw
            model = parse_urdf_text(text, str(loaded.path))
    except XacroContent as exc:
        raise UserError(_xacro_refusal(exc, spec["urdf"], loaded), where) from None
    except UrdfParseError as exc:
        raise UserErrors([UserError(message, where) for message in exc.messages]) from None
    loader_error = rerun_loader_error(text)
    if loader_error is not None:  # what text_for_rerun does not repair: refused now rather than a crash in `run`
        raise UserError(f"Rerun's URDF loader cannot read {loaded.path.name}: {loader_error}", where)
    _check_depth(model, loaded, where)
    if notes:
        warn(f"Rerun's URDF loader refuses parts of {loaded.path.name} that ROS tolerates; drawn without: {'; '.join(notes)}", where)
    return RobotUrdf(loaded, model, text)


def _refused_by_the_os(confinement: Confinement, path: Path) -> bool:
    """Whether `check_read` refused `path` for what the OS says of it (a symlink loop, a name too long, a FIFO, a file
    where a folder is expected) rather than for its place: a path it cannot follow leaves the robot nothing to read."""
    try:
        return confinement.may_read(resolved(path))
    except Unresolvable:
        return True


def compile_robot(ctx: CompileContext, key: str, spec: dict[str, Any], sources: SourceNames) -> CompiledRobot | None:
    """The robot's plan and parsed URDF. `sources` names the values of each source that compiled (a source the config
    defines but that failed is reported once, by itself); None: only its data knows them (`validate --no-data`)."""
    problems = ctx.problems
    here = ("robots", key)
    confinement = ctx.confinement
    package_paths: dict[str, Path] = {}
    followed = True  # every folder and the xacro file are paths the OS can follow; else nothing below them is read
    for name, written in spec.get("package_paths", {}).items():
        where = ctx.where(*here, "package_paths", name)
        named = Path(os.path.abspath(ctx.config_dir / written))  # as written, `..` folded; check_read resolves it
        try:
            folder = package_paths[name] = confinement.check_read(named, f"package '{name}' folder", where)
        except UserError as exc:  # kept, unresolved: xacro and mesh lookups check each file they read, and say which one
            problems.extend(exc)
            package_paths[name] = named
            followed = followed and not _refused_by_the_os(confinement, named)
            continue
        if not folder.is_dir():
            problems.add(f"package '{name}' directory not found: {folder}", where)
    urdf_spec = spec["urdf"]
    if isinstance(urdf_spec, dict) and "xacro" in urdf_spec:  # what the OS says of the file, at its own key
        named = Path(os.path.abspath(ctx.config_dir / urdf_spec["xacro"]))
        try:
            confinement.check_read(named, "xacro file", ctx.where(*here, "urdf", "xacro"))
        except UserError as exc:
            if _refused_by_the_os(confinement, named):  # refused by its place: urdf/load.py says so, at the urdf key
                problems.extend(exc)
                followed = False
    if not followed:
        return None
    try:
        urdf = load_urdf(ctx, key, spec, package_paths)
    except UserError as exc:
        problems.extend(exc)
        return None
    loaded, model = urdf.loaded, urdf.model
    urdf_path = loaded.path
    package_paths = {**loaded.package_paths, **package_paths}  # the config's own entries win
    keep_collisions = spec.get("collision_geometries", "drop") == "keep"
    # Resolve every mesh (so Rerun needs no ROS environment); only those that will be drawn must resolve.
    where_urdf = ctx.where(*here, "urdf")
    resolution = resolve_meshes(model.meshes, package_paths, urdf_path, confinement, where_urdf)
    drawn = [m for m in model.meshes if m.kind == "visual" or keep_collisions]
    for error in [*resolution.refused, *garbage_meshes(drawn, resolution.resolved, urdf_path.name, where_urdf)]:
        problems.extend(error)  # a mesh outside the config's roots, leaving its package, or not a mesh: never allowed
    missing = [m for m in resolution.missing if m.kind == "visual" or keep_collisions]
    if missing:
        reasons = resolution.reasons
        shown = listing(
            [f"{m.uri} ({m.kind} of link '{m.link}'{': ' + reasons[m.uri] if m.uri in reasons else ''})" for m in missing],
            limit=5,
            separator="; ",
        )
        message = f"{len(missing)} mesh(es) do not resolve: {shown}"
        if spec.get("allow_missing_meshes", False):
            warn(f"{message}; they will be invisible (allow_missing_meshes: true)", ctx.where(*here))
        else:
            problems.add(
                f"{message}; set package_paths for the package, or allow_missing_meshes: true to draw the robot without them",
                ctx.where(*here, "package_paths") if "package_paths" in spec else ctx.where(*here, "urdf"),
            )

    joints_spec = spec.get("joints")
    if joints_spec is None:  # a scene (table, camera mounts): nothing moves
        moving = [j.name for j in model.joints if j.moving and j.mimic is None]
        if moving:
            problems.add(
                f"URDF '{model.name}' has moving joints ({listing(moving)}) but the robot has no joints section; "
                "add joints: {source: ..., map: ...} (hold joints the data lacks)",
                ctx.where(*here),
            )
            return None
        source_name: str | None = None
        joints = JointMapping()
    else:
        source_name = joints_spec["source"]
        if source_name not in sources:
            if source_name in ctx.source_names:
                return None  # the source itself is broken and already reported
            problems.add(
                f"no source named '{source_name}'; sources are: {', '.join(sources) or 'none'}",
                ctx.where(*here, "joints", "source"),
            )
            return None
        joints = compile_joints(ctx, key, joints_spec, sources[source_name], model)
    prefix = spec.get("entity_path_prefix", key).strip("/")
    plan = RobotPlan(
        key=key,
        urdf_path=urdf_path,
        urdf_text=rewrite_mesh_uris(urdf.rerun_text, resolution.resolved),
        urdf_origin=loaded.origin,
        urdf_sha256=loaded.sha256,
        robot_name=model.name,
        root_link=model.root_link,
        links=model.links,
        joint_links=tuple((j.name, j.parent, j.child) for j in model.joints),
        entity_path_prefix=f"/{prefix}",
        frame_prefix=spec.get("frame_prefix", ""),
        keep_collisions=keep_collisions,
        source=source_name,
        channels=joints.channels,
        holds=joints.holds,
        mimics=joints.mimics,
        on_violation=joints.on_violation,
        where=ctx.where(*here),
        nan_policy=(joints_spec or {}).get("nan", "error"),
    )
    return CompiledRobot(plan, model)

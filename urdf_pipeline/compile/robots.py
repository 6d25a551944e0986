"""Compile one robot: load its URDF, resolve every mesh, map its joints."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..confine import Confinement, Unresolvable, refuse_url, resolved
from ..errors import UserError, UserErrors, Where, listing, shown, warn
from ..plan import RobotPlan
from ..sources import robot_description
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
from .comparisons import appearance_of
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
    if "mcap" in urdf:
        return exc.advice("expand it as xacro, and give the URDF as a file", what=f"the robot description in {shown(urdf['mcap'])}")
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
    from_bag = isinstance(spec["urdf"], dict) and "mcap" in spec["urdf"]
    if from_bag:
        loaded = _bag_urdf(ctx, key, spec["urdf"])
    else:
        loaded = load_urdf_source(spec["urdf"], package_paths, ctx.config_dir, ctx.confinement, where, ctx.xacro_budget)
    try:
        is_file = isinstance(spec["urdf"], str) or "robot_descriptions" in spec["urdf"]  # an expanded xacro or MJCF has no lines
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


def _bag_urdf(ctx: CompileContext, key: str, urdf: dict[str, Any]) -> LoadedUrdf:
    """`urdf: {mcap: FILE, topic: /robot_description}`: the last std_msgs/msg/String on the topic (capped in size, read
    at compile); relative mesh paths start from the bag's folder, `package://` from the robot's package_paths."""
    where = ctx.where("robots", key, "urdf", "mcap")
    refuse_url(str(urdf["mcap"]), "MCAP file", where)
    path = ctx.confinement.check_read(Path(os.path.abspath(ctx.config_dir / urdf["mcap"])), "MCAP file", where)
    if not path.is_file():
        raise UserError(f"MCAP file not found: {path} (paths are relative to the config file)", where)
    topic = urdf.get("topic", "/robot_description")
    text = robot_description(path, topic, ctx.where("robots", key, "urdf", "topic") if "topic" in urdf else where)
    return LoadedUrdf(text, path, f"mcap {urdf['mcap']} topic {topic}")


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
    package_paths, folders_followed = _package_paths(ctx, key, spec)
    xacro_followed = _xacro_file_followed(ctx, key, spec)  # checked even when a folder was not: every problem is reported
    if not (folders_followed and xacro_followed):
        return None
    try:
        urdf = load_urdf(ctx, key, spec, package_paths)
    except UserError as exc:
        ctx.problems.extend(exc)
        return None
    loaded, model = urdf.loaded, urdf.model
    keep_collisions = spec.get("collision_geometries", "drop") == "keep"
    package_paths = {**loaded.package_paths, **package_paths}  # the config's own entries win
    mesh_files = _mesh_files(ctx, key, spec, urdf, package_paths, keep_collisions)
    mapped = _robot_joints(ctx, key, spec, sources, model)
    if mapped is None:
        return None
    source_name, joints = mapped
    prefix = spec.get("entity_path_prefix", key).strip("/")
    plan = RobotPlan(
        key=key,
        urdf_path=loaded.path,
        urdf_text=rewrite_mesh_uris(urdf.rerun_text, mesh_files),
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
        where=ctx.where("robots", key),
        nan_policy=(spec.get("joints") or {}).get("nan", "error"),
        appearance=appearance_of(spec),
    )
    return CompiledRobot(plan, model)


def _package_paths(ctx: CompileContext, key: str, spec: dict[str, Any]) -> tuple[dict[str, Path], bool]:
    """The config's package folders, each checked where it is written, and whether the OS can follow all of them. A
    folder refused for its place is kept unresolved: xacro and mesh lookups check each file they read, and say which."""
    confinement = ctx.confinement
    package_paths: dict[str, Path] = {}
    followed = True  # every folder is a path the OS can follow; else nothing below it is read
    for name, written in spec.get("package_paths", {}).items():
        where = ctx.where("robots", key, "package_paths", name)
        named = Path(os.path.abspath(ctx.config_dir / written))  # as written, `..` folded; check_read resolves it
        try:
            folder = package_paths[name] = confinement.check_read(named, f"package '{name}' folder", where)
        except UserError as exc:
            ctx.problems.extend(exc)
            package_paths[name] = named
            followed = followed and not _refused_by_the_os(confinement, named)
            continue
        if not folder.is_dir():
            ctx.problems.add(f"package '{name}' directory not found: {folder}", where)
    return package_paths, followed


def _xacro_file_followed(ctx: CompileContext, key: str, spec: dict[str, Any]) -> bool:
    """Whether the OS can follow the robot's xacro file (True for any other URDF form). What the OS says of the file is
    reported at its own key; a file refused for its place is left to urdf/load.py, which says so at the urdf key."""
    urdf_spec = spec["urdf"]
    if not (isinstance(urdf_spec, dict) and "xacro" in urdf_spec):
        return True
    named = Path(os.path.abspath(ctx.config_dir / urdf_spec["xacro"]))
    try:
        ctx.confinement.check_read(named, "xacro file", ctx.where("robots", key, "urdf", "xacro"))
    except UserError as exc:
        if _refused_by_the_os(ctx.confinement, named):
            ctx.problems.extend(exc)
            return False
    return True


def _mesh_files(
    ctx: CompileContext, key: str, spec: dict[str, Any], urdf: RobotUrdf, package_paths: dict[str, Path], keep_collisions: bool
) -> dict[str, Path]:
    """Every mesh URI's file, so Rerun needs no ROS environment. Only meshes that will be drawn must resolve; a mesh
    outside the config's roots, leaving its package, or not a mesh is never allowed, drawn or not."""
    urdf_path = urdf.loaded.path
    meshes = urdf.model.meshes
    where_urdf = ctx.where("robots", key, "urdf")
    resolution = resolve_meshes(meshes, package_paths, urdf_path, ctx.confinement, where_urdf)
    drawn = [m for m in meshes if m.kind == "visual" or keep_collisions]
    for error in [*resolution.refused, *garbage_meshes(drawn, resolution.resolved, urdf_path.name, where_urdf)]:
        ctx.problems.extend(error)
    reasons = resolution.reasons
    missing = [
        f"{m.uri} ({m.kind} of link '{m.link}'{': ' + reasons[m.uri] if m.uri in reasons else ''})"
        for m in resolution.missing
        if m.kind == "visual" or keep_collisions
    ]
    if missing:
        _missing_meshes(ctx, key, spec, missing)
    return resolution.resolved


def _missing_meshes(ctx: CompileContext, key: str, spec: dict[str, Any], missing: list[str]) -> None:
    """Drawn meshes that do not resolve (each described: URI, link, why): an error pointing at package_paths (the usual
    fix), or a warning when the config allows the robot to be drawn without them."""
    message = f"{len(missing)} mesh(es) do not resolve: {listing(missing, limit=5, separator='; ')}"
    if spec.get("allow_missing_meshes", False):
        warn(f"{message}; they will be invisible (allow_missing_meshes: true)", ctx.where("robots", key))
    else:
        ctx.problems.add(
            f"{message}; set package_paths for the package, or allow_missing_meshes: true to draw the robot without them",
            ctx.where("robots", key, "package_paths") if "package_paths" in spec else ctx.where("robots", key, "urdf"),
        )


def _robot_joints(
    ctx: CompileContext, key: str, spec: dict[str, Any], sources: SourceNames, model: UrdfModel
) -> tuple[str | None, JointMapping] | None:
    """The robot's source and joint mapping; an empty mapping and no source for a scene (a robot without `joints`, such
    as a table or camera mounts: refused if its URDF has moving joints). None: refused, or its source failed by itself."""
    joints_spec = spec.get("joints")
    if joints_spec is None:
        moving = [j.name for j in model.joints if j.moving and j.mimic is None]
        if moving:
            ctx.problems.add(
                f"URDF '{model.name}' has moving joints ({listing(moving)}) but the robot has no joints section; "
                "add joints: {source: ..., map: ...} (hold joints the data lacks)",
                ctx.where("robots", key),
            )
            return None
        return None, JointMapping()
    source_name: str = joints_spec["source"]
    if source_name not in sources:
        if source_name in ctx.source_names:
            return None  # the source itself is broken and already reported
        ctx.problems.add(
            f"no source named '{source_name}'; sources are: {', '.join(sources) or 'none'}",
            ctx.where("robots", key, "joints", "source"),
        )
        return None
    return source_name, compile_joints(ctx, key, joints_spec, sources[source_name], model)

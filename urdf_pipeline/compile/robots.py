"""Compile one robot: load its URDF, resolve every mesh, map its joints."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..config.document import Document
from ..confine import confinement_for
from ..errors import Problems, UserError, UserErrors, listing, warn
from ..plan import HeldJoint, JointChannel, MimicJoint, OnViolation, RobotPlan, SourcePlan
from ..urdf.load import LoadedUrdf, load_urdf_source
from ..urdf.meshes import garbage_meshes, resolve_meshes, rewrite_mesh_uris
from ..urdf.model import UrdfModel, UrdfParseError, parse_urdf_text
from ..urdf.repair import rerun_loader_error, text_for_rerun
from .joint_mapping import compile_joints


def load_urdf(key: str, spec: dict[str, Any], package_paths: dict[str, Path], document: Document) -> tuple[LoadedUrdf, UrdfModel, str]:
    """The loaded URDF, its model and the text for Rerun's loader (axes normalised, what Rerun refuses repaired, with a
    warning saying what); the model is read from that text, so a visual dropped there needs no mesh."""
    loaded = load_urdf_source(key, spec["urdf"], package_paths, document)
    where = document.where("robots", key, "urdf")
    try:
        is_file = isinstance(spec["urdf"], str) or "xacro" not in spec["urdf"]  # an expanded xacro has no lines to point at
        model = parse_urdf_text(loaded.text, str(loaded.path), source_lines=is_file)
        text, notes = text_for_rerun(loaded.text, str(loaded.path))
        if text is not loaded.text:  # repaired: the model is read from what Rerun will draw
            model = parse_urdf_text(text, str(loaded.path))
    except UrdfParseError as exc:
        raise UserErrors([UserError(message, where) for message in exc.messages]) from None
    loader_error = rerun_loader_error(text)
    if loader_error is not None:  # what text_for_rerun does not repair: refused now rather than a crash in `run`
        raise UserError(f"Rerun's URDF loader cannot read {loaded.path.name}: {loader_error}", where)
    if notes:
        warn(f"Rerun's URDF loader refuses parts of {loaded.path.name} that ROS tolerates; drawn without: {'; '.join(notes)}", where)
    return loaded, model, text


def compile_robot(
    key: str, spec: dict[str, Any], sources: dict[str, SourcePlan], defined: set[str], document: Document, problems: Problems
) -> tuple[RobotPlan, UrdfModel] | None:
    """The robot's plan and parsed URDF. `sources` holds the sources that compiled; `defined` every name in the config
    (a broken source is reported once)."""
    here = ("robots", key)
    package_paths = {name: (document.file.parent / folder).resolve() for name, folder in spec.get("package_paths", {}).items()}
    confinement = confinement_for(document.file)
    for name, folder in package_paths.items():
        try:  # kept in package_paths: xacro and mesh lookups check each file they read, and say which one
            confinement.check_read(folder, f"package '{name}' folder", document.where(*here, "package_paths", name))
        except UserError as exc:
            problems.extend(exc)
            continue
        if not folder.is_dir():
            problems.add(f"package '{name}' directory not found: {folder}", document.where(*here, "package_paths", name))
    try:
        loaded, model, rerun_text = load_urdf(key, spec, package_paths, document)
    except UserError as exc:
        problems.extend(exc)
        return None
    urdf_path = loaded.path
    package_paths = {**loaded.package_paths, **package_paths}  # the config's own entries win
    keep_collisions = spec.get("collision_geometries", "drop") == "keep"
    # Resolve every mesh (so Rerun needs no ROS environment); only those that will be drawn must resolve.
    where_urdf = document.where(*here, "urdf")
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
            warn(f"{message}; they will be invisible (allow_missing_meshes: true)", document.where(*here))
        else:
            problems.add(
                f"{message}; set package_paths for the package, or allow_missing_meshes: true to draw the robot without them",
                document.where(*here, "package_paths") if "package_paths" in spec else document.where(*here, "urdf"),
            )

    joints_spec = spec.get("joints")
    if joints_spec is None:  # a scene (table, camera mounts): nothing moves
        moving = [j.name for j in model.joints if j.moving and j.mimic is None]
        if moving:
            problems.add(
                f"URDF '{model.name}' has moving joints ({', '.join(moving)}) but the robot has no joints section; "
                "add joints: {source: ..., map: ...} (hold joints the data lacks)",
                document.where(*here),
            )
            return None
        source_name: str | None = None
        channels: tuple[JointChannel, ...] = ()
        holds: tuple[HeldJoint, ...] = ()
        mimics: tuple[MimicJoint, ...] = ()
        on_violation: OnViolation = "error"
    else:
        source = sources.get(joints_spec["source"])
        if source is None:
            if joints_spec["source"] in defined:
                return None  # the source itself is broken and already reported
            problems.add(
                f"no source named '{joints_spec['source']}'; sources are: {', '.join(sources) or 'none'}",
                document.where(*here, "joints", "source"),
            )
            return None
        source_name = source.name
        channels, holds, mimics, on_violation = compile_joints(key, joints_spec, source.names, model, document, problems)
    prefix = spec.get("entity_path_prefix", key).strip("/")
    plan = RobotPlan(
        key=key,
        urdf_path=urdf_path,
        urdf_text=rewrite_mesh_uris(rerun_text, resolution.resolved),
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
        channels=channels,
        holds=holds,
        mimics=mimics,
        on_violation=on_violation,
        where=document.where(*here),
        nan_policy=(joints_spec or {}).get("nan", "error"),
    )
    return plan, model

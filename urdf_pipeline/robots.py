"""Compile one robot: load its URDF, resolve every mesh, map its joints."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .document import Document
from .errors import Problems, UserError, listing, warn
from .joint_mapping import compile_joints
from .meshes import resolve_meshes, rewrite_mesh_uris
from .plan import HeldJoint, JointChannel, MimicJoint, OnViolation, RobotPlan, SourcePlan
from .urdf_model import UrdfModel, UrdfParseError, parse_urdf_text
from .urdf_sources import LoadedUrdf, load_urdf_source


def load_urdf(key: str, spec: dict[str, Any], package_paths: dict[str, Path], document: Document) -> tuple[LoadedUrdf, UrdfModel]:
    loaded = load_urdf_source(key, spec["urdf"], package_paths, document)
    try:
        return loaded, parse_urdf_text(loaded.text, str(loaded.path))
    except UrdfParseError as exc:
        raise UserError(str(exc), document.where("robots", key, "urdf")) from None


def _check_mimics(model: UrdfModel, key: str, document: Document, problems: Problems) -> None:
    names = {j.name for j in model.joints}
    for joint in model.joints:
        if joint.mimic is not None and joint.mimic.joint not in names:
            problems.add(
                f"URDF joint '{joint.name}' mimics '{joint.mimic.joint}', which the URDF lacks", document.where("robots", key, "urdf")
            )


def compile_robot(
    key: str, spec: dict[str, Any], sources: dict[str, SourcePlan], defined: set[str], document: Document, problems: Problems
) -> tuple[RobotPlan, UrdfModel] | None:
    """The robot's plan and parsed URDF. `sources` holds the sources that compiled; `defined` every name in the config
    (a broken source is reported once)."""
    here = ("robots", key)
    package_paths = {name: (document.file.parent / folder).resolve() for name, folder in spec.get("package_paths", {}).items()}
    for name, folder in package_paths.items():
        if not folder.is_dir():
            problems.add(f"package '{name}' directory not found: {folder}", document.where(*here, "package_paths", name))
    try:
        loaded, model = load_urdf(key, spec, package_paths, document)
    except UserError as exc:
        problems.extend(exc)
        return None
    _check_mimics(model, key, document, problems)
    urdf_path = loaded.path
    package_paths = {**loaded.package_paths, **package_paths}  # the config's own entries win
    keep_collisions = spec.get("collision_geometries", "drop") == "keep"
    # Resolve every mesh (so Rerun needs no ROS environment); only those that will be drawn must resolve.
    resolution = resolve_meshes(model.meshes, package_paths, urdf_path.parent)
    missing = [m for m in resolution.missing if m.kind == "visual" or keep_collisions]
    if missing:
        shown = listing([f"{m.uri} ({m.kind} of link '{m.link}')" for m in missing], limit=5, separator="; ")
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
        urdf_text=rewrite_mesh_uris(loaded.text, resolution.resolved),
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

"""Resolve mesh URIs the way a user expects, so an unresolved mesh is an error and not an invisible robot."""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote
from xml.sax.saxutils import escape

from .urdf_model import MeshRef

_MESH_FILENAME = re.compile(r"""(<mesh\b[^>]*?\bfilename\s*=\s*)(["'])(.*?)\2""", re.DOTALL)


@dataclass(frozen=True)
class MeshResolution:
    resolved: dict[str, Path]  # uri -> existing file
    missing: tuple[MeshRef, ...]


def package_roots(package: str) -> list[Path]:
    """ROS_PACKAGE_PATH entries (the entry itself or entry/NAME) and AMENT_PREFIX_PATH prefixes (prefix/share/NAME)."""
    roots: list[Path] = []
    for entry in filter(None, os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)):
        base = Path(entry)
        roots += [base] if base.name == package else [base / package]
    for entry in filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)):
        roots.append(Path(entry) / "share" / package)
    return roots


def candidates(uri: str, package_paths: Mapping[str, Path], urdf_dir: Path) -> list[Path]:
    """Where a mesh URI may live, in the documented order."""
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://") :].partition("/")
        roots: list[Path] = []
        if package in package_paths:
            roots.append(package_paths[package])
        roots += package_roots(package)
        roots += [ancestor for ancestor in (urdf_dir, *urdf_dir.parents) if ancestor.name == package]
        roots.append(urdf_dir)
        return [root / unquote(rest) for root in roots]
    if uri.startswith("file://"):
        return [Path(unquote(uri[len("file://") :]))]
    if "://" in uri:
        return []
    path = Path(uri)
    return [path if path.is_absolute() else urdf_dir / path]


def resolve_meshes(meshes: tuple[MeshRef, ...], package_paths: Mapping[str, Path], urdf_dir: Path) -> MeshResolution:
    resolved: dict[str, Path] = {}
    missing: list[MeshRef] = []
    for mesh in meshes:
        if mesh.uri in resolved:
            continue
        found = next((c for c in candidates(mesh.uri, package_paths, urdf_dir) if c.is_file()), None)
        if found is None:
            missing.append(mesh)
        else:
            resolved[mesh.uri] = found.resolve()
    return MeshResolution(resolved, tuple(missing))


def rewrite_mesh_uris(urdf_text: str, resolved: Mapping[str, Path]) -> str:
    """Replace every resolved mesh URI by its absolute path, so Rerun needs no ROS environment."""

    def substitute(match: re.Match[str]) -> str:
        uri = match.group(3)
        target = resolved.get(uri)
        return (
            match.group(0)
            if target is None
            else f"{match.group(1)}{match.group(2)}{escape(str(target), {chr(34): '&quot;', chr(39): '&apos;'})}{match.group(2)}"
        )

    return _MESH_FILENAME.sub(substitute, urdf_text)

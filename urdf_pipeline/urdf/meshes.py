"""Resolve mesh URIs as ROS, pinocchio and Gazebo do (the forms and their order: docs/urdf.md, Meshes), read only from
local files, so an unresolved mesh is an error and not an invisible robot.

Every file found must also be one the config may read (`confine.py`) and hold a mesh Rerun draws (a cheap header check:
Rerun copies whatever bytes the file holds into the recording, and the viewer then fails on them).
"""

from __future__ import annotations

import os
import posixpath
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import BinaryIO
from urllib.parse import unquote

from ..confine import Confinement, file_state
from ..errors import UserError, Where
from .model import MeshRef
from .xml_text import doctype_line

_MESH_FILENAME = re.compile(r"""(<mesh\b[^>]*?\bfilename\s*=\s*)(["'])(.*?)\2""", re.DOTALL)
_PACKAGE_SCHEMES = ("package", "model")
_NETWORK_SCHEMES = ("http", "https", "ftp")


class MeshUriRefused(Exception):
    """A URI that reaches outside what it names (a package path leaving its package): an error, whatever the config allows."""


class MeshUriUnread(Exception):
    """A URI form that is not read (network schemes, unknown schemes): the mesh is unresolved, with this reason."""


@dataclass(frozen=True)
class MeshResolution:
    resolved: dict[str, Path]  # uri -> existing file the config may read
    missing: tuple[MeshRef, ...]
    reasons: dict[str, str]  # uri -> why a missing mesh's form is not read
    refused: tuple[UserError, ...]  # meshes that leave their package or the config's read roots


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
    """Where a mesh URI may live, in the documented order. Raises MeshUriRefused or MeshUriUnread."""
    scheme, separator, body = uri.partition("://")
    if not separator:
        plain = Path(uri)
        return [plain if plain.is_absolute() else urdf_dir / plain]
    if scheme in _PACKAGE_SCHEMES:
        package, _, rest = body.partition("/")
        if not package:  # package:///NAME/path
            package, _, rest = rest.lstrip("/").partition("/")
        rest = unquote(rest).lstrip("/")
        if not package:
            raise MeshUriUnread(f"{scheme}:// names no package")
        if package in (".", "..") or posixpath.normpath(rest).split("/")[0] == "..":
            raise MeshUriRefused(f"leaves its package '{package}' (a {scheme}:// path must stay inside the package's folder)")
        roots: list[Path] = []
        if package in package_paths:
            roots.append(package_paths[package])
        roots += package_roots(package)
        roots += [ancestor for ancestor in (urdf_dir, *urdf_dir.parents) if ancestor.name == package]
        roots.append(urdf_dir)
        return [root / rest for root in roots]
    if scheme == "file":
        path = unquote(body)
        if not path.startswith("/"):
            raise MeshUriUnread("a file:// URI holds an absolute path (file:///abs/path.stl); a host part is not read")
        return [Path(path)]
    if scheme.lower() in _NETWORK_SCHEMES:
        raise MeshUriUnread(f"{scheme}:// is not read: a run has no network; download the mesh and use a local path")
    raise MeshUriUnread(f"{scheme}:// is not a form ROS resolves (package://, model://, file:// or a path)")


def resolve_meshes(
    meshes: tuple[MeshRef, ...], package_paths: Mapping[str, Path], urdf_path: Path, confinement: Confinement, where: Where | None
) -> MeshResolution:
    """Each URI's file (the first candidate that exists), refused when it leaves its package or the config's roots."""
    resolved: dict[str, Path] = {}
    missing: list[MeshRef] = []
    reasons: dict[str, str] = {}
    refused: dict[str, UserError] = {}
    for mesh in meshes:
        if mesh.uri in resolved or mesh.uri in refused:
            continue
        what = f"{urdf_path.name}, link '{mesh.link}': {mesh.kind} mesh"
        try:
            options = candidates(mesh.uri, package_paths, urdf_path.parent)
        except MeshUriRefused as exc:
            refused[mesh.uri] = UserError(f"{what} {mesh.uri} {exc}", where)
            continue
        except MeshUriUnread as exc:
            missing.append(mesh)
            reasons[mesh.uri] = str(exc)
            continue
        try:
            found = _first_file(options, confinement, f"{what} {mesh.uri}, file", where)
        except UserError as exc:  # a loop, a name too long, a FIFO: inside the roots, so its cause may be told
            refused[mesh.uri] = exc
            continue
        if found is None and len(options) == 1 and not confinement.may_read(options[0]):
            found = options[0]  # refused below whether it exists or not: a config learns nothing of files outside
        if found is None:
            missing.append(mesh)
            continue
        shown = what if str(found) == mesh.uri else f"{what} {mesh.uri}, file"
        try:
            resolved[mesh.uri] = confinement.check_read(found, shown, where)
        except UserError as exc:
            refused[mesh.uri] = exc
    return MeshResolution(resolved, tuple(missing), reasons, tuple(refused.values()))


def _first_file(options: list[Path], confinement: Confinement, what: str, where: Where | None) -> Path | None:
    """The first candidate that is a regular file. One the OS cannot follow (or a FIFO) is a user error with its cause
    when it lies inside the config's roots; outside them it counts as absent (the read rule refuses it by its place)."""
    for candidate in options:
        try:
            if file_state(candidate, what, where) == "file":
                return candidate
        except UserError:
            if confinement.may_read(candidate):
                raise
    return None


def garbage_meshes(meshes: list[MeshRef], resolved: Mapping[str, Path], urdf_name: str, where: Where | None) -> list[UserError]:
    """A user error per resolved file among `meshes` that does not hold a mesh Rerun draws."""
    errors: dict[Path, UserError] = {}
    for mesh in meshes:
        path = resolved.get(mesh.uri)
        if path is None or path in errors:
            continue
        problem = mesh_content_problem(path)
        if problem is not None:
            errors[path] = UserError(
                f"{urdf_name}, link '{mesh.link}': {mesh.kind} mesh {path} {problem}; replace it with the real mesh file", where
            )
    return list(errors.values())


def rewrite_mesh_uris(urdf_text: str, resolved: Mapping[str, Path]) -> str:
    """Replace every resolved mesh URI by its absolute path, so Rerun needs no ROS environment."""

    def substitute(match: re.Match[str]) -> str:
        uri = match.group(3)
        target = resolved.get(uri)
        return match.group(0) if target is None else f"{match.group(1)}{match.group(2)}{_xml_attribute(str(target))}{match.group(2)}"

    return _MESH_FILENAME.sub(substitute, urdf_text)


# Content checks: a header or a bounded read per format Rerun's viewer draws (its media type comes from the suffix).
_HEAD = 1 << 16  # bytes read where a format has no fixed header
_OBJ_HEAD = 1 << 20  # an OBJ may open with a long comment or material block
_CHUNK = 1 << 16


def mesh_content_problem(path: Path) -> str | None:
    """Why the file at `path` is not a mesh Rerun draws ("is empty", ...), or None. Cached per size and mtime."""
    try:
        stat = path.stat()
    except OSError as exc:
        return f"cannot be read ({exc.strerror})"
    return _content_problem(path, stat.st_size, stat.st_mtime_ns)


@lru_cache(maxsize=8192)
def _content_problem(path: Path, size: int, mtime_ns: int) -> str | None:
    check = _CHECKS.get(path.suffix.lower())
    if check is None:
        return f"has the suffix '{path.suffix}', not one of the mesh formats Rerun draws ({', '.join(_CHECKS)})"
    if size == 0:
        return "is empty"
    try:
        with path.open("rb") as file:
            return check(file, size)
    except OSError as exc:
        return f"cannot be read ({exc.strerror})"


def _stl(file: BinaryIO, size: int) -> str | None:
    head = file.read(84)
    if len(head) == 84 and 84 + 50 * int.from_bytes(head[80:84], "little") == size:
        return None  # binary STL: an 80-byte header, the triangle count, 50 bytes per triangle
    text = head + file.read(_HEAD)
    if text.lstrip().startswith(b"solid") and (b"facet" in text or b"endsolid" in text):
        return None
    return "is not an STL file (neither binary, 84 + 50 bytes per triangle, nor ASCII, `solid ... facet ...`)"


def _dae(file: BinaryIO, size: int) -> str | None:
    """The root element only, from at most 64 KiB; a DOCTYPE (where entities are declared) is refused unparsed."""
    parser: ET.XMLPullParser[ET.Element] = ET.XMLPullParser(events=("start",))
    seen = b""
    while len(seen) < _HEAD:
        chunk = file.read(4096)
        if not chunk:
            break
        seen += chunk
        if doctype_line(seen) is not None:
            return "is not a COLLADA file (it declares a DOCTYPE, which COLLADA files do not)"
        try:
            parser.feed(chunk)
            events = list(parser.read_events())
        except ET.ParseError as exc:
            return f"is not a COLLADA file (not XML: {exc})"
        elements = [event[-1] for event in events if isinstance(event[-1], ET.Element)]
        if elements:
            tag = str(elements[0].tag).rpartition("}")[2]
            return None if tag == "COLLADA" else f"is not a COLLADA file (its XML root is <{tag}>, not <COLLADA>)"
    return "is not a COLLADA file (no XML root element in its first 64 KiB)"


def _obj(file: BinaryIO, size: int) -> str | None:
    head = file.read(_OBJ_HEAD)
    if b"\0" in head:
        return "is not a Wavefront OBJ file (it is binary, OBJ is text)"
    if re.search(rb"(?m)^[ \t]*v[ \t]", head):
        return None
    return "is not a Wavefront OBJ file (no vertex line `v x y z` in its first MiB)"


def _gltf(file: BinaryIO, size: int) -> str | None:
    head = file.read(_CHUNK)
    if not head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{"):
        return 'is not a glTF file (not a JSON object with "asset")'
    tail = b""
    while head:  # "asset" may follow large embedded buffers: scan in chunks, keeping an overlap
        if b'"asset"' in tail + head:
            return None
        tail, head = head[-8:], file.read(_CHUNK)
    return 'is not a glTF file (a JSON object without "asset")'


def _glb(file: BinaryIO, size: int) -> str | None:
    head = file.read(12)
    if len(head) == 12 and head[:4] == b"glTF" and int.from_bytes(head[4:8], "little") in (1, 2):
        return None
    return "is not a binary glTF file (it does not start with the magic `glTF` and a version)"


_CHECKS: dict[str, Callable[[BinaryIO, int], str | None]] = {".stl": _stl, ".dae": _dae, ".obj": _obj, ".gltf": _gltf, ".glb": _glb}


def _xml_attribute(text: str) -> str:
    """`text` escaped for an XML attribute value (xml.sax.saxutils.escape would import urllib.request: 40 ms of
    every command)."""
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;").replace("'", "&apos;")

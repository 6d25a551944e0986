"""What a robot's visuals occupy around the frames they hang on: one box per visual, in its frame.

Link origins alone frame a robot badly: a gripper or a foot reaches well beyond the last frame. So the camera also
frames the corners of each visual's box, read from the recording's own geometry (the chunks the viewer draws). A mesh
that cannot be read counts as a cube of FALLBACK_HALF_SIZE around its pose: the picture may then be a little loose,
never cut.
"""

from __future__ import annotations

import hashlib
import json
import re
import struct
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from ..execute import rotation_matrices

if TYPE_CHECKING:
    from rerun.chunk import Chunk

FALLBACK_HALF_SIZE = 0.1  # metres: a visual whose extent cannot be read
_UNIT_CUBE = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
_PARSE_ERRORS = (ValueError, KeyError, IndexError, TypeError, AttributeError, struct.error, ET.ParseError, UnicodeDecodeError)
Box = tuple[np.ndarray, np.ndarray]  # low and high corner (3 each)


@dataclass(frozen=True)
class GeometryBoxes:
    """Each visual's box: its entity, the frame it hangs on and its 8 corners in that frame."""

    paths: tuple[str, ...]
    frames: tuple[str, ...]
    corners: np.ndarray  # G x 8 x 3

    def under(self, prefixes: Iterable[str]) -> GeometryBoxes:
        """The boxes of the entities under any of `prefixes` (a robot's `entity_path_prefix`; "/" for all)."""
        roots = tuple("/" + prefix.strip("/") for prefix in prefixes)
        keep = [index for index, path in enumerate(self.paths) if _under(path, roots)]
        return GeometryBoxes(tuple(self.paths[i] for i in keep), tuple(self.frames[i] for i in keep), self.corners[keep])

    def world(self, poses: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """The corners in the root frame, given the frames' poses (rotations T x G x 3 x 3, positions T x G x 3, one
        per box, as RecordedTransforms.poses gives for `frames`): (T * G * 8) x 3, NaN where a frame is not placed."""
        rotations, positions = poses
        placed = np.einsum("tgij,gkj->tgki", rotations, self.corners) + positions[:, :, None, :]
        return placed.reshape(-1, 3)


@dataclass
class _Visual:
    """What one geometry entity holds, gathered from its chunks."""

    frame: str | None = None
    shapes: list[Box] = field(default_factory=list)
    unreadable: bool = False
    translations: np.ndarray | None = None
    quaternions: np.ndarray | None = None
    scales: np.ndarray | None = None


def _under(path: str, roots: tuple[str, ...]) -> bool:
    return any(root == "/" or path == root or path.startswith(root + "/") for root in roots)


def geometry_boxes(chunks: Sequence[Chunk]) -> GeometryBoxes:
    """The boxes of every static visual of a recording's chunks (`under` picks a robot's)."""
    visuals: dict[str, _Visual] = {}
    frames_of: dict[str, str] = {}  # entity -> its own CoordinateFrame, for descendants without one
    cache: dict[bytes, Box | None] = {}
    for chunk in chunks:
        if not chunk.is_static:
            continue
        path = chunk.entity_path
        batch = chunk.to_record_batch()
        frame = _last(batch, "CoordinateFrame:frame")
        if frame is not None:
            frames_of[path] = frame
        shapes, unreadable = _shapes(batch, cache)
        poses = _poses(batch)
        if not (shapes or unreadable or poses or frame is not None):
            continue
        visual = visuals.setdefault(path, _Visual())
        visual.frame = frame if frame is not None else visual.frame
        visual.shapes += shapes
        visual.unreadable |= unreadable
        if poses:
            visual.translations, visual.quaternions, visual.scales = poses
    paths: list[str] = []
    frames: list[str] = []
    corners: list[np.ndarray] = []
    for path, visual in visuals.items():
        if not visual.shapes and not visual.unreadable:
            continue
        frame = visual.frame or _inherited(path, frames_of)
        if frame is None:
            continue  # not placed in any frame: the viewer cannot place it either
        paths.append(path)
        frames.append(frame)
        corners.append(_corners(visual))
    return GeometryBoxes(tuple(paths), tuple(frames), np.stack(corners) if corners else np.zeros((0, 8, 3)))


def _inherited(path: str, frames_of: dict[str, str]) -> str | None:
    while path not in ("", "/"):
        path = path.rsplit("/", 1)[0] or "/"
        if path in frames_of:
            return frames_of[path]
    return None


def _last(batch: pa.RecordBatch, name: str) -> str | None:
    if name not in batch.schema.names:
        return None
    values = [v for row in batch.column(name).to_pylist() if row for v in row]
    return str(values[-1]) if values else None


def _floats(batch: pa.RecordBatch, name: str, width: int) -> np.ndarray | None:
    """A list-of-vectors component's values, all rows' instances together (K x width), or None."""
    if name not in batch.schema.names:
        return None
    values = batch.column(name).flatten()
    if pa.types.is_fixed_size_list(values.type) or pa.types.is_list(values.type):
        values = values.flatten()
    flat = np.asarray(values.to_numpy(zero_copy_only=False), dtype=np.float64)
    return flat.reshape(-1, width) if len(flat) % width == 0 and len(flat) else None


def _poses(batch: pa.RecordBatch) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None] | None:
    parts = (
        _floats(batch, "InstancePoses3D:translations", 3),
        _floats(batch, "InstancePoses3D:quaternions", 4),
        _floats(batch, "InstancePoses3D:scales", 3),
    )
    return parts if any(part is not None for part in parts) else None


def _shapes(batch: pa.RecordBatch, cache: dict[bytes, Box | None]) -> tuple[list[Box], bool]:
    """The boxes of the geometry components in one chunk, and whether one could not be read."""
    shapes: list[Box] = []
    unreadable = False
    names = batch.schema.names
    if "Asset3D:blob" in names:
        media = _last(batch, "Asset3D:media_type") or ""
        for blob in batch.column("Asset3D:blob").flatten():
            data = np.asarray(blob.values.to_numpy(zero_copy_only=False), dtype=np.uint8).tobytes() if blob.is_valid else b""
            key = hashlib.blake2b(media.encode() + b"\0" + data, digest_size=16).digest()
            if key not in cache:
                cache[key] = mesh_box(data, media)
            box = cache[key]
            unreadable |= box is None
            shapes += [box] if box is not None else []
    vertices = _floats(batch, "Mesh3D:vertex_positions", 3)
    if vertices is not None:
        shapes.append(_box(vertices))
    shapes += _primitives(batch)
    return shapes, unreadable


def _primitives(batch: pa.RecordBatch) -> list[Box]:
    """Boxes, ellipsoids, cylinders (along z, centred) and capsules (from the origin along +z) as Rerun draws them."""
    shapes: list[Box] = []
    for kind in ("Boxes3D", "Ellipsoids3D"):
        half = _floats(batch, f"{kind}:half_sizes", 3)
        if half is not None:
            centers = _floats(batch, f"{kind}:centers", 3)
            middle = centers if centers is not None and len(centers) == len(half) else np.zeros_like(half)
            shapes.append(((middle - np.abs(half)).min(axis=0), (middle + np.abs(half)).max(axis=0)))
    lengths, radii = _floats(batch, "Cylinders3D:lengths", 1), _floats(batch, "Cylinders3D:radii", 1)
    if lengths is not None:
        extent = np.array([_max(radii), _max(radii), _max(lengths) / 2])
        centers = _floats(batch, "Cylinders3D:centers", 3)
        middle = centers if centers is not None else np.zeros((1, 3))
        shapes.append(((middle - extent).min(axis=0), (middle + extent).max(axis=0)))
    lengths, radii = _floats(batch, "Capsules3D:lengths", 1), _floats(batch, "Capsules3D:radii", 1)
    if lengths is not None:
        radius = _max(radii)
        shapes.append((np.full(3, -radius), np.array([radius, radius, _max(lengths) + radius])))
    return shapes


def _max(values: np.ndarray | None) -> float:
    return float(np.abs(values).max()) if values is not None and len(values) else 0.0


def _box(points: np.ndarray) -> Box:
    finite = points[np.isfinite(points).all(axis=1)]
    if not len(finite):
        raise ValueError("no finite vertex")
    return finite.min(axis=0), finite.max(axis=0)


def _corners(visual: _Visual) -> np.ndarray:
    """The visual's 8 box corners in its frame: its shapes' boxes (a fallback cube if unreadable) through each
    instance pose, boxed again."""
    boxes = list(visual.shapes)
    if visual.unreadable:
        boxes.append((np.full(3, -FALLBACK_HALF_SIZE), np.full(3, FALLBACK_HALF_SIZE)))
    low = np.min([low for low, _ in boxes], axis=0)
    high = np.max([high for _, high in boxes], axis=0)
    local = (low + high) / 2 + _UNIT_CUBE * (high - low) / 2  # 8 x 3
    count = max((len(part) for part in (visual.translations, visual.quaternions, visual.scales) if part is not None), default=0) or 1
    translations = _rows(visual.translations, count, np.zeros(3))
    quaternions = _rows(visual.quaternions, count, np.array([0.0, 0.0, 0.0, 1.0]))
    quaternions[np.linalg.norm(quaternions, axis=1) < 1e-12] = (0.0, 0.0, 0.0, 1.0)
    scales = _rows(visual.scales, count, np.ones(3))
    placed = np.einsum("nij,nkj->nki", rotation_matrices(quaternions), local[None] * scales[:, None, :]) + translations[:, None, :]
    flat = placed.reshape(-1, 3)
    return (flat.min(axis=0) + flat.max(axis=0)) / 2 + _UNIT_CUBE * (flat.max(axis=0) - flat.min(axis=0)) / 2


def _rows(values: np.ndarray | None, count: int, default: np.ndarray) -> np.ndarray:
    """One row per instance: a component with fewer values repeats its last, as Rerun's instance poses do."""
    if values is None or not len(values):
        return np.broadcast_to(default, (count, len(default))).copy()
    index = np.minimum(np.arange(count), len(values) - 1)
    rows = values[index]
    rows[~np.isfinite(rows).all(axis=1)] = default
    return rows


# ------------------------------------------------------------------------------------------------------- mesh files


def mesh_box(data: bytes, media_type: str) -> Box | None:
    """The box of a mesh file's vertices in its own coordinates, or None when it cannot be read here."""
    readers = {
        "model/stl": _stl,
        "model/obj": _obj,
        "model/vnd.collada+xml": _collada,
        "model/gltf-binary": _gltf,
        "model/gltf+json": _gltf,
    }
    reader = readers.get(media_type.split(";")[0].strip().lower())
    if reader is None or not data:
        return None
    try:
        return reader(data)
    except _PARSE_ERRORS:
        return None


def _stl(data: bytes) -> Box:
    if len(data) >= 84:
        (count,) = struct.unpack_from("<I", data, 80)
        if len(data) == 84 + 50 * count and count:
            triangles = np.frombuffer(
                data, dtype=np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), count=count, offset=84
            )
            return _box(triangles["v"].reshape(-1, 3).astype(np.float64))
    text = data.decode("ascii")
    return _box(_numbers(re.findall(r"vertex\s+(\S+)\s+(\S+)\s+(\S+)", text)))


def _obj(data: bytes) -> Box:
    text = data.decode("utf-8", "replace")
    return _box(_numbers(re.findall(r"^\s*v\s+(\S+)\s+(\S+)\s+(\S+)", text, flags=re.MULTILINE)))


def _numbers(rows: list[tuple[str, str, str]]) -> np.ndarray:
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def _tag(element: ET.Element) -> str:
    return element.tag.rsplit("}", 1)[-1]


def _collada(data: bytes) -> Box:
    """COLLADA: the POSITION arrays of the geometries the visual scene instances, through its nodes' matrices, in the
    asset's unit. A file not z-up (Rerun may turn it) counts as the cube around its farthest vertex."""
    root = ET.fromstring(data)
    elements = list(root.iter())
    by_id = {element.get("id"): element for element in elements if element.get("id")}
    asset = next((e for e in root if _tag(e) == "asset"), None)
    unit = next((float(e.get("meter", "1")) for e in (asset if asset is not None else []) if _tag(e) == "unit"), 1.0)
    up = next((str(e.text).strip() for e in (asset if asset is not None else []) if _tag(e) == "up_axis"), "Y_UP")
    positions = {geometry_id: _collada_positions(element, by_id) for geometry_id, element in by_id.items() if _tag(element) == "geometry"}
    placed = _collada_scene(root, positions)
    if not placed:
        placed = [points for points in positions.values() if len(points)]
    points = np.concatenate(placed) * unit
    if up != "Z_UP":
        reach = float(np.linalg.norm(points[np.isfinite(points).all(axis=1)], axis=1).max())
        return np.full(3, -reach), np.full(3, reach)
    return _box(points)


def _collada_positions(geometry: ET.Element, by_id: dict[str | None, ET.Element]) -> np.ndarray:
    """A geometry's vertex positions: its <vertices>' POSITION input, the float_array of that source."""
    found: list[np.ndarray] = []
    for element in geometry.iter():
        if _tag(element) == "input" and element.get("semantic") == "POSITION" and element.get("source", "").startswith("#"):
            source = by_id.get(element.get("source", "")[1:])
            if source is None or _tag(source) != "source":
                continue
            array = next((e for e in source.iter() if _tag(e) == "float_array"), None)
            accessor = next((e for e in source.iter() if _tag(e) == "accessor"), None)
            stride = int(accessor.get("stride", "3")) if accessor is not None else 3
            if array is None or not array.text or stride < 3:
                continue
            values = np.array(array.text.split(), dtype=np.float64)
            found.append(values[: len(values) // stride * stride].reshape(-1, stride)[:, :3])
    return np.concatenate(found) if found else np.zeros((0, 3))


def _collada_scene(root: ET.Element, positions: dict[str | None, np.ndarray]) -> list[np.ndarray]:
    """Positions of each instanced geometry through the matrices of the nodes above it (<matrix>, <translate>,
    <scale>; a <rotate> is taken as the farthest reach, through a matrix of the right length)."""
    scenes = [e for e in root.iter() if _tag(e) == "visual_scene"]
    placed: list[np.ndarray] = []
    stack = [(node, np.eye(4)) for scene in scenes for node in scene if _tag(node) == "node"]
    while stack:
        node, parent = stack.pop()
        matrix = parent @ _node_matrix(node)
        for child in node:
            tag = _tag(child)
            if tag == "node":
                stack.append((child, matrix))
            elif tag == "instance_geometry" and child.get("url", "").startswith("#"):
                points = positions.get(child.get("url", "")[1:])
                if points is not None and len(points):
                    placed.append(points @ matrix[:3, :3].T + matrix[:3, 3])
    return placed


def _node_matrix(node: ET.Element) -> np.ndarray:
    matrix = np.eye(4)
    for child in node:
        tag = _tag(child)
        values = np.array((child.text or "").split(), dtype=np.float64) if tag in ("matrix", "translate", "scale", "rotate") else None
        step = np.eye(4)
        if tag == "matrix" and values is not None and len(values) == 16:
            step = values.reshape(4, 4)
        elif tag == "translate" and values is not None and len(values) == 3:
            step[:3, 3] = values
        elif tag == "scale" and values is not None and len(values) == 3:
            step[:3, :3] = np.diag(values)
        elif tag == "rotate" and values is not None and len(values) == 4:
            step[:3, :3] = _axis_angle(values[:3], np.radians(values[3]))
        matrix = matrix @ step
    return matrix


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    norm = float(np.linalg.norm(axis))
    if norm == 0:
        return np.eye(3)
    x, y, z = axis / norm
    cross = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def _gltf(data: bytes) -> Box:
    """glTF (binary or JSON): the POSITION accessors' min and max (the format requires them), as the cube around their
    farthest corner, grown by every node's translation and largest scale: the node tree and the y-up convention are
    not followed here, so the cube holds the mesh however they turn it."""
    if data[:4] == b"glTF":
        (length,) = struct.unpack_from("<I", data, 12)
        document = json.loads(data[20 : 20 + length])
    else:
        document = json.loads(data)
    accessors = document["accessors"]
    corners = []
    for mesh in document.get("meshes", []):
        for primitive in mesh.get("primitives", []):
            accessor = accessors[primitive["attributes"]["POSITION"]]
            corners += [accessor["min"][:3], accessor["max"][:3]]
    nodes = document.get("nodes", [])
    scale = max((float(np.abs(np.array(node.get("scale", [1, 1, 1]), dtype=np.float64)).max()) for node in nodes), default=1.0)
    shift = sum(float(np.linalg.norm(np.array(node.get("translation", [0, 0, 0]), dtype=np.float64))) for node in nodes)
    reach = float(np.linalg.norm(np.array(corners, dtype=np.float64), axis=1).max()) * max(scale, 1.0) + shift
    return np.full(3, -reach), np.full(3, reach)

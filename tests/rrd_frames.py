"""Read the frame graph back out of a written .rrd and compose poses, independently of the package."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

Edge = tuple[str, np.ndarray]  # parent frame, 4x4 pose of child in parent


def quat_xyzw_to_matrix(q: list[float]) -> np.ndarray:
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def pose(translation: list[float] | None, quaternion: list[float] | None) -> np.ndarray:
    matrix = np.eye(4)
    if quaternion is not None:
        matrix[:3, :3] = quat_xyzw_to_matrix(quaternion)
    if translation is not None:
        matrix[:3, 3] = translation
    return matrix


@dataclass
class RecordedFrames:
    static: dict[str, Edge]  # child -> edge
    temporal: dict[str, dict[object, Edge]]  # child -> time -> edge
    static_entities: dict[str, str]  # child -> entity that logged its static edge

    def at(self, time: object) -> dict[str, Edge]:
        """Edges in effect at `time`: the temporal value overrides the static one for the same child."""
        edges = dict(self.static)
        for child, by_time in self.temporal.items():
            if time in by_time:
                edges[child] = by_time[time]
        return edges

    def world_pose(self, frame: str, time: object, root: str) -> np.ndarray:
        edges = self.at(time)
        result = np.eye(4)
        current, hops = frame, 0
        while current != root:
            parent, local = edges[current]  # KeyError: the frame does not reach the root
            result = local @ result
            current, hops = parent, hops + 1
            assert hops < 1000, "cycle"
        return result


def read_frames(path: Path | list[Path], timeline: str) -> RecordedFrames:
    """The frames of one recording, or of several that belong together (a split layout's model and one layer)."""
    static: dict[str, Edge] = {}
    static_entities: dict[str, str] = {}
    temporal: dict[str, dict[object, Edge]] = {}
    chunks = [chunk for one in ([path] if isinstance(path, Path) else path) for chunk in RrdReader(one).stream().to_chunks()]
    for chunk in chunks:
        batch = chunk.to_record_batch()
        if "Transform3D:child_frame" not in batch.schema.names:
            continue
        if not chunk.is_static and timeline not in batch.schema.names:
            continue  # on another timeline (e.g. an arm by frame_index beside a base by message time)
        if timeline in batch.schema.names and pa.types.is_timestamp(batch.schema.field(timeline).type):
            # Nanosecond timestamps as integers: no pandas needed to read them back.
            index = batch.schema.get_field_index(timeline)
            batch = batch.set_column(index, timeline, batch.column(index).cast(pa.int64()))
        rows = batch.to_pylist()
        for row in rows:
            if row["Transform3D:child_frame"] is None:  # a row left out (joints.nan: drop_row)
                continue
            child = row["Transform3D:child_frame"][0]
            parent = row["Transform3D:parent_frame"][0]
            translation = (row.get("Transform3D:translation") or [None])[0]
            quaternion = (row.get("Transform3D:quaternion") or [None])[0]
            edge = (parent, pose(translation, quaternion))
            if chunk.is_static:
                assert child not in static, f"two static edges for {child}: {static_entities[child]} and {chunk.entity_path}"
                static[child] = edge
                static_entities[child] = chunk.entity_path
            else:
                temporal.setdefault(child, {})[row[timeline]] = edge
    return RecordedFrames(static, temporal, static_entities)


def rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle of the rotation between two rotation matrices, radians."""
    # ||Ra - Rb||_F = 2 sqrt(2) sin(angle / 2); unlike arccos of the trace, exact near zero.
    distance = np.linalg.norm(a[:3, :3] - b[:3, :3])
    return float(2 * np.arcsin(min(1.0, distance / (2 * np.sqrt(2)))))

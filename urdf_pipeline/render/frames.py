"""Link poses over a recording, from the transforms it holds: what the viewer composes, done with numpy.

A picture's camera frames every link and visual at the time it shows, so the poses are read from the recording itself
(Rerun's own FK results, not computed again) and composed by the run's own `execute.compose`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..execute import Pose, compose, rotation_matrices

if TYPE_CHECKING:
    from rerun.chunk import Chunk

TimelineKind = Literal["sequence", "timestamp", "duration"]
CHILD, PARENT = "Transform3D:child_frame", "Transform3D:parent_frame"
TRANSLATION, QUATERNION = "Transform3D:translation", "Transform3D:quaternion"
MAX_TIMES = 2048  # times composed at most: every row of a shorter segment, evenly spread rows of a longer one


@dataclass(frozen=True)
class Timeline:
    name: str
    kind: TimelineKind


@dataclass(frozen=True)
class _Edges:
    """Rows of one kind (static, or temporal on one timeline): child and parent frame (codes into the frame names)
    per row, translation and unit quaternion."""

    times: np.ndarray  # int64 (sequence, or nanoseconds); zeros for static rows
    child: np.ndarray  # int64 codes
    parent: np.ndarray  # int64 codes, -1 when the row names no parent
    translation: np.ndarray  # N x 3
    quaternion: np.ndarray  # N x 4, (x, y, z, w)


@dataclass(frozen=True)
class RecordedTransforms:
    """Every Transform3D of a recording (or of a model and a layer together), on the chosen timeline."""

    frames: tuple[str, ...]  # the frame names the edges' codes index
    static: _Edges
    temporal: _Edges
    timeline: Timeline | None

    @property
    def times(self) -> np.ndarray:
        """The times at which some transform changes, sorted."""
        return np.unique(self.temporal.times)

    def positions(self, root: str, frames: Iterable[str], times: np.ndarray | None = None) -> np.ndarray:
        """World positions (times x frames x 3, NaN where a frame is not placed) of `frames` at `times` (default: the
        recording's times, at most MAX_TIMES of them spread evenly)."""
        return self.poses(root, frames, times)[1]

    def poses(self, root: str, frames: Iterable[str], times: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (times x frames x 3 x 3) and positions (times x frames x 3) of `frames`, NaN where a frame
        is not placed: what a mesh hanging on a frame needs to be placed too."""
        if times is None:
            times = self.sampled_times()
        wanted = list(frames)
        placed = _compose(self, root, times, set(wanted))
        count = len(times)
        if not wanted:
            return np.zeros((count, 0, 3, 3)), np.zeros((count, 0, 3))
        found = [placed.get(frame, (np.full((count, 3), np.nan), np.full((count, 4), np.nan))) for frame in wanted]
        return rotation_matrices(np.stack([q for _, q in found], axis=1)), np.stack([t for t, _ in found], axis=1)

    def sampled_times(self) -> np.ndarray:
        times = self.times
        if not len(times):
            return np.zeros(1, dtype=np.int64)  # static only: one pose
        if len(times) > MAX_TIMES:
            times = times[np.unique(np.linspace(0, len(times) - 1, MAX_TIMES).round().astype(np.int64))]
        return times


def transform_timelines(chunks: Sequence[Chunk], entities: Iterable[str] = ()) -> list[Timeline]:
    """The timelines temporal transforms are logged on; those of `entities` (the robots' FK) first, then sequence
    timelines before time ones, then by name."""
    preferred = {"/" + e.strip("/") for e in entities}
    found: dict[str, tuple[int, Timeline]] = {}
    for chunk in chunks:
        if chunk.is_static:
            continue
        schema = chunk.to_record_batch().schema
        if CHILD not in schema.names:
            continue
        rank = 0 if chunk.entity_path in preferred else 1
        for name in chunk.timeline_names:
            timeline = Timeline(name, _kind(schema.field(name).type))
            if name not in found or rank < found[name][0]:
                found[name] = (rank, timeline)
    order = {"sequence": 0, "duration": 1, "timestamp": 2}
    return [t for _, t in sorted(found.values(), key=lambda item: (item[0], order[item[1].kind], item[1].name))]


def read_transforms(chunks: Sequence[Chunk], timeline: Timeline | None) -> RecordedTransforms:
    names: dict[str, int] = {}
    static: list[_Edges] = []
    temporal: list[_Edges] = []
    for chunk in chunks:
        batch = chunk.to_record_batch()
        if CHILD not in batch.schema.names:
            continue
        if chunk.is_static:
            static.append(_edges(batch, None, names))
        elif timeline is not None and timeline.name in batch.schema.names:
            temporal.append(_edges(batch, timeline.name, names))
    return RecordedTransforms(tuple(names), _concatenate(static), _concatenate(temporal), timeline)


def _kind(datatype: pa.DataType) -> TimelineKind:
    if pa.types.is_timestamp(datatype):
        return "timestamp"
    if pa.types.is_duration(datatype):
        return "duration"
    return "sequence"


def _edges(batch: pa.RecordBatch, timeline: str | None, names: dict[str, int]) -> _Edges:
    """One row per transform instance; rows without a child frame (left out by `nan: drop_row`) are dropped."""
    children = batch.column(CHILD)
    counts = np.asarray(pc.fill_null(pc.list_value_length(children), 0), dtype=np.int64)
    rows = np.repeat(np.arange(batch.num_rows), counts)
    if timeline is None:
        times = np.zeros(len(rows), dtype=np.int64)
    else:
        times = np.asarray(batch.column(timeline).cast(pa.int64()).to_numpy(zero_copy_only=False))[rows]
    child = _codes(children.flatten(), names)
    parent = _instances(batch, PARENT, counts, names=names)[:, 0].astype(np.int64)
    translation = np.nan_to_num(_instances(batch, TRANSLATION, counts, 3), nan=0.0)
    quaternion = _instances(batch, QUATERNION, counts, 4)
    quaternion[~np.isfinite(quaternion).all(axis=1)] = (0.0, 0.0, 0.0, 1.0)
    return _Edges(times, child, parent, translation, quaternion / np.linalg.norm(quaternion, axis=1, keepdims=True))


def _codes(text: pa.Array, names: dict[str, int]) -> np.ndarray:
    """Frame names as codes into `names` (grown as new names appear): a dictionary per column, not a str per row."""
    encoded = pc.dictionary_encode(text)
    lookup = np.array([names.setdefault(name, len(names)) for name in encoded.dictionary.to_pylist()] + [-1], dtype=np.int64)
    indices = np.asarray(pc.fill_null(encoded.indices, -1), dtype=np.int64)
    return lookup[indices]


def _instances(batch: pa.RecordBatch, name: str, counts: np.ndarray, width: int = 1, names: dict[str, int] | None = None) -> np.ndarray:
    """The component's value per instance of the child frame (NaN, or code -1 for a frame name, where a row has none
    or as many values as it has frames)."""
    out = np.full((int(counts.sum()), width), np.nan if names is None else -1.0)
    if name not in batch.schema.names:
        return out
    column = batch.column(name)
    own = np.asarray(pc.fill_null(pc.list_value_length(column), 0), dtype=np.int64)
    flat = column.flatten()
    values = (_codes(flat, names).astype(np.float64) if names is not None else np.asarray(flat.flatten(), dtype=np.float64)).reshape(
        -1, width
    )
    row = np.repeat(np.arange(len(own)), own)
    position = (np.cumsum(counts) - counts)[row] + np.arange(len(row)) - (np.cumsum(own) - own)[row]
    keep = (own == counts)[row]
    out[position[keep]] = values[keep]
    return out


def _concatenate(parts: list[_Edges]) -> _Edges:
    if not parts:
        none = np.zeros(0, dtype=np.int64)
        return _Edges(none, none, none, np.zeros((0, 3)), np.zeros((0, 4)))
    return _Edges(
        *(np.concatenate([getattr(p, field) for p in parts]) for field in ("times", "child", "parent", "translation", "quaternion"))
    )


def _compose(transforms: RecordedTransforms, root: str, times: np.ndarray, wanted: set[str]) -> dict[str, Pose]:
    """World poses (times x 3, times x 4) of the frames in `wanted` that reach `root`; the latest temporal value at or
    before a time overrides the static one, as in the viewer."""
    static, temporal, names = transforms.static, transforms.temporal, transforms.frames
    parent_of = {int(c): int(p) for c, p in zip(static.child, static.parent, strict=True)}  # the last static row wins
    static_row = {int(c): row for row, c in enumerate(static.child)}
    order = np.lexsort((temporal.times, temporal.child))  # by child, then time
    children, starts = np.unique(temporal.child[order], return_index=True)
    ends = np.append(starts[1:], len(order))[: len(starts)]
    temporal_rows = {int(c): order[s:e] for c, s, e in zip(children, starts, ends, strict=True)}
    for child, rows in temporal_rows.items():
        parent_of.setdefault(child, int(temporal.parent[rows[0]]))
    code = {name: index for index, name in enumerate(names)}
    top = code.get(root, -2)

    def local(child: int) -> Pose:
        return _local(static, static_row.get(child), temporal, temporal_rows.get(child), times)

    world = compose(top, [(parent, child) for child, parent in parent_of.items()], local, len(times))
    placed = {root: world[top]} if root in wanted else {}
    placed.update((names[child], pose) for child, pose in world.items() if child >= 0 and names[child] in wanted)
    return placed


def _local(static: _Edges, row: int | None, temporal: _Edges, rows: np.ndarray | None, times: np.ndarray) -> Pose:
    """A child's transform at each time: its latest temporal row at or before it, else its static edge (NaN if none)."""
    translation = np.full((len(times), 3), np.nan)
    quaternion = np.full((len(times), 4), np.nan)
    if row is not None:
        translation[:] = static.translation[row]
        quaternion[:] = static.quaternion[row]
    if rows is not None:
        at = np.searchsorted(temporal.times[rows], times, side="right") - 1
        known = at >= 0
        translation[known] = temporal.translation[rows[at[known]]]
        quaternion[known] = temporal.quaternion[rows[at[known]]]
    return translation, quaternion

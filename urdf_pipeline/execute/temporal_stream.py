"""Temporal edges as a lazy stream: the source's vectors -> one Transform3D per row on `/calibration/temporal/CHILD`, with the statistics the checks after the data pass need."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np
import pyarrow as pa

from ..compile import describe_temporal_edge
from ..errors import Problems
from ..plan import NamedSource, RecordingPlan, TemporalEdgePlan
from ..sources import CallbackErrors, raw_matrix
from .transform_lenses import float_vectors, transform_lenses, transform_lists, transform_stream

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream


@dataclass
class TemporalEdgeStats:
    rows: int = 0
    nonfinite_rows: int = 0
    nonfinite_by_value: dict[str, int] = field(default_factory=dict)
    zero_quaternion_rows: int = 0

    def add(self, finite: np.ndarray, names: Sequence[str], usable: np.ndarray) -> None:
        """A batch's rows: `finite` (rows x values, named `names`) says which values are finite, `usable` which rows
        `placed_poses` placed; a row of finite values that is not usable has an all-zero quaternion."""
        whole = finite.all(axis=1)
        self.rows += len(finite)
        self.nonfinite_rows += int((~whole).sum())
        self.zero_quaternion_rows += int((whole & ~usable).sum())
        for name, count in zip(names, (~finite).sum(axis=0), strict=True):
            if count:
                self.nonfinite_by_value[name] = self.nonfinite_by_value.get(name, 0) + int(count)


class EdgeRows(Protocol):
    """What the checks after the pass read of a temporal edge: the edge and its statistics (named values or a bag's /tf)."""

    edge: TemporalEdgePlan
    stats: TemporalEdgeStats


class TemporalEdgeValues:
    """The first lens's function: source vectors -> one list<struct> Transform3D batch per row, with statistics."""

    def __init__(self, edge: TemporalEdgePlan, source: NamedSource) -> None:
        self.edge = edge
        self.source = source
        self.width = len(source.names)
        self.columns = np.array([*edge.translation_indices, *edge.quaternion_indices], dtype=np.intp)
        self.value_names = (*edge.translation_names, *edge.quaternion_names)
        self.stats = TemporalEdgeStats()
        self._lock = threading.Lock()

    def __call__(self, vectors: pa.Array) -> pa.Array:
        return self.placed(vectors)[0]

    def placed(self, vectors: pa.Array) -> tuple[pa.Array, np.ndarray]:
        """The list<struct> batch, and which rows it places (the others, NaN or an all-zero quaternion, hold an
        identity and are counted: a run refuses them after its pass, a live view leaves them out)."""
        picked = raw_matrix(self.source, vectors, self.columns, f"temporal edge {self.edge.parent} -> {self.edge.child}")[:, self.columns]
        rows = len(picked)
        translation, quaternion, usable = placed_poses(picked[:, :3], picked[:, 3:])
        with self._lock:
            self.stats.add(np.isfinite(picked), self.value_names, usable)
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32))
        frames = (pa.array([frame] * rows, pa.string()) for frame in (self.edge.parent, self.edge.child))
        return transform_lists(offsets, float_vectors(translation), float_vectors(quaternion), *frames), usable


def placed_poses(translation: np.ndarray, quaternion: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(translation, unit quaternion, usable rows) of rows x 3 and rows x 4 values. A row with a NaN or infinite
    value or an all-zero quaternion is not usable: it stops a run after the data pass (a live view leaves it out), and
    holds a harmless identity meanwhile so the batch stays valid."""
    finite = np.isfinite(translation).all(axis=1) & np.isfinite(quaternion).all(axis=1)
    norms = np.linalg.norm(np.where(np.isfinite(quaternion), quaternion, 0.0), axis=1)
    usable = finite & (norms >= 1e-9)
    placed_translation = np.where(usable[:, None], translation, 0.0)
    placed_quaternion = np.where(usable[:, None], quaternion / np.where(usable, norms, 1.0)[:, None], [0.0, 0.0, 0.0, 1.0])
    return placed_translation, placed_quaternion, usable


def temporal_edge_streams(plan: RecordingPlan, errors: CallbackErrors) -> tuple[list[LazyChunkStream], list[TemporalEdgeValues]]:
    """One stream per source that temporal edges read, every edge from one read of it (compute lens -> scatter lens
    onto Transform3D). The source is opened here on its own: a source that also drives a robot is read twice (once for
    the FK, once here), which keeps the FK stream untouched."""
    from ..sources import module_for

    streams: list[LazyChunkStream] = []
    all_values: list[TemporalEdgeValues] = []
    for source in plan.sources:
        edges = [edge for edge in plan.temporal_edges if edge.source == source.name and edge.tf_topic is None]  # /tf: tf_stream.py
        if not edges:
            continue
        values = [TemporalEdgeValues(edge, source) for edge in edges]
        stream = module_for(source).open_stream(source)
        pairs = [
            transform_lenses(
                stream,
                f"/__urdf_pipeline/temporal_edge_batches{v.edge.entity}",
                f"urdf_pipeline:TemporalEdgeBatch:{v.edge.entity}",
                v.edge.entity,
                v,
                errors,
            )
            for v in values
        ]
        streams.append(transform_stream(stream, pairs, errors))
        all_values += values
    return streams, all_values


def check_temporal_edges(values: Sequence[EdgeRows], problems: Problems) -> None:
    """After the data pass: every temporal edge had rows, all finite, with non-zero quaternions."""
    for edge_values in values:
        edge, stats = edge_values.edge, edge_values.stats
        if stats.rows == 0:
            problems.add(
                f"{describe_temporal_edge(edge)}: source '{edge.source}' yielded zero rows; frame '{edge.child}' would never be placed",
                edge.where,
            )
            continue
        if stats.nonfinite_rows:
            counts = ", ".join(f"{name} {count}" for name, count in stats.nonfinite_by_value.items())
            problems.add(
                f"{describe_temporal_edge(edge)}: {stats.nonfinite_rows} of {stats.rows} rows are NaN or infinite (per value: {counts})",
                edge.where,
            )
        if stats.zero_quaternion_rows:
            problems.add(
                f"{describe_temporal_edge(edge)}: {stats.zero_quaternion_rows} of {stats.rows} rows have an all-zero quaternion "
                f"({', '.join(edge.quaternion_names)}), which is no rotation at all",
                edge.where,
            )

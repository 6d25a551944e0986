"""Forward kinematics as a lazy, columnar stream: two lenses per robot (compute batches, scatter to Transform3D)."""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from ..progress import RowProgress
from ..sources import CallbackErrors, JointValueMapper, raw_matrix
from .transform_lenses import transform_lenses, transform_stream

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream
    from rerun.urdf import UrdfTree

    from ..sources import SourceStream


def _batch_component(robot_key: str) -> str:
    return f"urdf_pipeline:JointTransformBatch:{robot_key}"


class JointTransformBatches:
    """The first lens's function: joint vectors -> per-row batches of joint transforms (Rerun's URDF FK)."""

    def __init__(self, mapper: JointValueMapper, tree: UrdfTree, progress: RowProgress | None = None) -> None:
        self.mapper = mapper
        self.progress = progress
        self.tree = tree
        self.names = pa.array(mapper.joint_names, pa.string())
        self._names_for_rows = lru_cache(maxsize=8)(self._build_names)

    def _build_names(self, rows: int) -> pa.Array:
        count = len(self.names)
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * count)
        values = pa.array(np.tile(np.asarray(self.names.to_pylist(), dtype=object), rows), pa.string())
        return pa.ListArray.from_arrays(offsets, values)

    def __call__(self, vectors: pa.Array) -> pa.Array:
        # Rows that name their values (MCAP JointState) are mapped by name, row by row; vectors by position.
        raw = raw_matrix(self.mapper.source, vectors, self.mapper.columns, f"robot '{self.mapper.robot.key}'")
        values, left_out = self.mapper.urdf_values(raw)
        rows, count = values.shape
        # Fresh float64 arrays per call: zero-copy slices of one big array make Rerun's FK quadratic.
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * count)
        value_lists = pa.ListArray.from_arrays(offsets, pa.array(values.reshape(-1)))
        batches = self.tree.compute_joint_transform_batches(self._names_for_rows(rows), value_lists)
        if left_out is not None:  # a null batch scatters to a row with no transform: nothing logged at that time
            batches = pa.ListArray.from_arrays(batches.offsets, batches.values, mask=pa.array(left_out))
        if self.progress is not None:
            self.progress.add(rows)
        return batches


def fk_stream(source: SourceStream, robots: list[tuple[str, str, JointTransformBatches]], errors: CallbackErrors) -> LazyChunkStream:
    """All robots driven by one source, from one read of it: (robot key, FK entity, batch function) each."""
    pairs = [
        transform_lenses(source, f"/__urdf_pipeline/{key}/joint_transform_batches", _batch_component(key), fk_entity, batches, errors)
        for key, fk_entity, batches in robots
    ]
    return transform_stream(source, pairs, errors)

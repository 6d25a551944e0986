"""Temporal edges: a pose read from a source row by row (a mobile base, a floating pelvis).

`{parent: world, child: base_link, source: base_pose, translation: [x, y, z], quaternion_xyzw: [qx, qy, qz, qw]}`
names values of the source. As a lazy stream: the source's vectors -> a DeriveLens whose function picks the seven
columns with numpy and returns one list<struct{translation, quaternion, parent_frame, child_frame}> per row (the
shape `compute_joint_transform_batches` returns) -> a scatter lens onto Transform3D at `/calibration/temporal/CHILD`.
Rows with NaN/infinite values or an all-zero quaternion are counted and stop the run after the data pass.
"""

from __future__ import annotations

import re
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from ..config.sidecar import EdgeSpec
from ..errors import Problems, closest, listing
from ..plan import Plan, SourcePlan, TemporalEdgePlan
from ..sources.callbacks import CallbackErrors
from ..sources.joint_values import raw_matrix

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

    from ..sources.stream import SourceStream

TEMPORAL_ENTITY = "/calibration/temporal"
_FLOAT3 = pa.list_(pa.field("item", pa.float32(), nullable=False), 3)
_FLOAT4 = pa.list_(pa.field("item", pa.float32(), nullable=False), 4)
_EDGE_STRUCT = pa.struct(
    [
        pa.field("translation", _FLOAT3, nullable=False),
        pa.field("quaternion", _FLOAT4, nullable=False),
        pa.field("parent_frame", pa.string(), nullable=False),
        pa.field("child_frame", pa.string(), nullable=False),
    ]
)


def describe(edge: TemporalEdgePlan) -> str:
    return f"temporal edge {edge.parent} -> {edge.child} ({edge.label}, source '{edge.source}')"


# --- compile ---------------------------------------------------------------------------------------------------


def compile_temporal_edge(
    edge: EdgeSpec, sources: dict[str, SourcePlan], defined: set[str], taken_entities: set[str], problems: Problems
) -> TemporalEdgePlan | None:
    """Check the source and every value name now (metadata only); values are checked in the data pass."""
    spec = edge.spec
    name = spec["source"]
    source = sources.get(name)
    if source is None:
        if name not in defined:
            problems.add(f"no source named '{name}'; sources are: {', '.join(sorted(defined)) or 'none'}", edge.where("source"))
        return None  # else the source itself is broken and already reported
    position = {value: index for index, value in enumerate(source.names)}
    missing = False
    for key in ("translation", "quaternion_xyzw"):
        for index, value in enumerate(spec[key]):
            if value not in position:
                close = closest(value, source.names)
                hint = f" (did you mean '{close}'?)" if close is not None else f"; it has: {listing(source.names)}"
                problems.add(f"source '{name}' has no value named '{value}'{hint}", edge.where(key, index))
                missing = True
    if missing:
        return None
    translation = tuple(spec["translation"])
    quaternion = tuple(spec["quaternion_xyzw"])
    return TemporalEdgePlan(
        parent=spec["parent"],
        child=spec["child"],
        source=name,
        translation_names=translation,  # type: ignore[arg-type]
        quaternion_names=quaternion,  # type: ignore[arg-type]
        translation_indices=tuple(position[v] for v in translation),  # type: ignore[arg-type]
        quaternion_indices=tuple(position[v] for v in quaternion),  # type: ignore[arg-type]
        entity=_entity_for(spec["child"], taken_entities),
        label=edge.label,
        where=edge.where(),
    )


def _entity_for(child: str, taken: set[str]) -> str:
    """`/calibration/temporal/CHILD`, with characters an entity path part cannot hold replaced, unique per edge."""
    part = re.sub(r"[^A-Za-z0-9_.-]", "_", child) or "_"
    entity = f"{TEMPORAL_ENTITY}/{part}"
    suffix = 2
    while entity in taken:
        entity = f"{TEMPORAL_ENTITY}/{part}_{suffix}"
        suffix += 1
    taken.add(entity)
    return entity


# --- data pass -------------------------------------------------------------------------------------------------


@dataclass
class TemporalEdgeStats:
    rows: int = 0
    nonfinite_rows: int = 0
    nonfinite_by_value: dict[str, int] = field(default_factory=dict)
    zero_quaternion_rows: int = 0


class TemporalEdgeValues:
    """The first lens's function: source vectors -> one list<struct> Transform3D batch per row, with statistics."""

    def __init__(self, edge: TemporalEdgePlan, source: SourcePlan) -> None:
        self.edge = edge
        self.source = source
        self.width = len(source.names)
        self.columns = np.array([*edge.translation_indices, *edge.quaternion_indices], dtype=np.intp)
        self.value_names = (*edge.translation_names, *edge.quaternion_names)
        self.stats = TemporalEdgeStats()
        self._lock = threading.Lock()

    def __call__(self, vectors: pa.Array) -> pa.Array:
        picked = raw_matrix(self.source, vectors, self.columns, f"temporal edge {self.edge.parent} -> {self.edge.child}")[:, self.columns]
        rows = len(picked)
        finite = np.isfinite(picked)
        bad_rows = ~finite.all(axis=1)
        norms = np.linalg.norm(np.where(finite[:, 3:], picked[:, 3:], 0.0), axis=1)
        zero = ~bad_rows & (norms < 1e-9)
        self._record(rows, finite, bad_rows, zero)
        # Bad rows stop the run after the data pass; give them a harmless identity so the batch stays valid.
        unusable = bad_rows | zero
        translation = np.where(unusable[:, None], 0.0, picked[:, :3])
        quaternion = np.where(unusable[:, None], [0.0, 0.0, 0.0, 1.0], picked[:, 3:] / np.where(unusable, 1.0, norms)[:, None])
        structs = pa.StructArray.from_arrays(
            [
                pa.FixedSizeListArray.from_arrays(pa.array(translation.astype(np.float32).reshape(-1)), 3).cast(_FLOAT3),
                pa.FixedSizeListArray.from_arrays(pa.array(quaternion.astype(np.float32).reshape(-1)), 4).cast(_FLOAT4),
                pa.array([self.edge.parent] * rows, pa.string()),
                pa.array([self.edge.child] * rows, pa.string()),
            ],
            fields=list(_EDGE_STRUCT),
        )
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32))
        return pa.ListArray.from_arrays(offsets, structs, type=pa.list_(pa.field("item", _EDGE_STRUCT, nullable=False)))

    def _record(self, rows: int, finite: np.ndarray, bad_rows: np.ndarray, zero: np.ndarray) -> None:
        per_value = (~finite).sum(axis=0)
        with self._lock:
            self.stats.rows += rows
            self.stats.nonfinite_rows += int(bad_rows.sum())
            self.stats.zero_quaternion_rows += int(zero.sum())
            for name, count in zip(self.value_names, per_value, strict=True):
                if count:
                    self.stats.nonfinite_by_value[name] = self.stats.nonfinite_by_value.get(name, 0) + int(count)


def _component(edge: TemporalEdgePlan) -> str:
    return f"urdf_pipeline:TemporalEdgeBatch:{edge.entity}"


def temporal_edge_stream(source: SourceStream, values: list[TemporalEdgeValues], errors: CallbackErrors) -> LazyChunkStream:
    """Every temporal edge of one source, from one read of it: compute lens -> scatter lens onto Transform3D."""
    import rerun as rr
    from rerun.chunk import DeriveLens, Selector

    computes, scatters = [], []
    for edge_values in values:
        edge = edge_values.edge
        component = _component(edge)
        computes.append(
            DeriveLens(source.component, output_entity=f"/__urdf_pipeline/temporal_edge_batches{edge.entity}").to_component(
                component, Selector(".").pipe(errors.wrap(edge_values))
            )
        )
        scatters.append(
            DeriveLens(component, output_entity=edge.entity, scatter=True)
            .to_component(rr.Transform3D.descriptor_translation(), Selector(".[].translation"))
            .to_component(rr.Transform3D.descriptor_quaternion(), Selector(".[].quaternion"))
            .to_component(rr.Transform3D.descriptor_parent_frame(), Selector(".[].parent_frame"))
            .to_component(rr.Transform3D.descriptor_child_frame(), Selector(".[].child_frame"))
        )
    return source.stream.lenses(computes, content=source.entity).lenses(scatters)


def temporal_edge_streams(plan: Plan, errors: CallbackErrors) -> tuple[list[LazyChunkStream], list[TemporalEdgeValues]]:
    """One stream per source that temporal edges read. The source is opened here on its own: a source that also
    drives a robot is read twice (once for the FK, once here), which keeps the FK stream untouched."""
    from ..sources import module_for

    streams: list[LazyChunkStream] = []
    all_values: list[TemporalEdgeValues] = []
    for source in plan.sources:
        edges = [edge for edge in plan.temporal_edges if edge.source == source.name]
        if not edges:
            continue
        values = [TemporalEdgeValues(edge, source) for edge in edges]
        streams.append(temporal_edge_stream(module_for(source).open_stream(source), values, errors))
        all_values += values
    return streams, all_values


def check_temporal_edges(values: list[TemporalEdgeValues], problems: Problems) -> None:
    """After the data pass: every temporal edge had rows, all finite, with non-zero quaternions."""
    for edge_values in values:
        edge, stats = edge_values.edge, edge_values.stats
        if stats.rows == 0:
            problems.add(
                f"{describe(edge)}: source '{edge.source}' yielded zero rows; frame '{edge.child}' would never be placed", edge.where
            )
            continue
        if stats.nonfinite_rows:
            counts = ", ".join(f"{name} {count}" for name, count in stats.nonfinite_by_value.items())
            problems.add(
                f"{describe(edge)}: {stats.nonfinite_rows} of {stats.rows} rows are NaN or infinite (per value: {counts})", edge.where
            )
        if stats.zero_quaternion_rows:
            problems.add(
                f"{describe(edge)}: {stats.zero_quaternion_rows} of {stats.rows} rows have an all-zero quaternion "
                f"({', '.join(edge.quaternion_names)}), which is no rotation at all",
                edge.where,
            )

"""The lens pair behind every derived transform stream (robot FK, temporal edges): compute, then scatter.

The compute lens turns each row of a source's component into one list of {translation, quaternion, parent_frame,
child_frame} structs (`TRANSFORMS`: the shape Rerun's `compute_joint_transform_batches` returns) on a private entity;
the scatter lens spreads each list into Transform3D rows on the output entity. The structs, and the Transform3D
component each field becomes (`transform_fields`, which a live view sends as columns), are built here only, so the
FK, the temporal edges and a live view cannot drift apart.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

if TYPE_CHECKING:
    from rerun import ComponentDescriptor
    from rerun.chunk import DeriveLens, LazyChunkStream

    from ..sources import CallbackErrors, SourceStream


def float_type(width: int) -> pa.DataType:
    """Rerun's vector type (Translation3D, Position3D, a quaternion): fixed_size_list<float32 not null>[width] (the
    viewer refuses a nullable item type, which is pyarrow's default)."""
    return pa.list_(pa.field("item", pa.float32(), nullable=False), width)


TRANSFORM = pa.struct(
    [
        pa.field("translation", float_type(3), nullable=False),
        pa.field("quaternion", float_type(4), nullable=False),
        pa.field("parent_frame", pa.string(), nullable=False),
        pa.field("child_frame", pa.string(), nullable=False),
    ]
)
TRANSFORMS = pa.list_(pa.field("item", TRANSFORM, nullable=False))  # one list of transforms per source row


def float_vectors(values: np.ndarray) -> pa.Array:
    """rows x N numbers as `float_type(N)` vectors."""
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).reshape(-1))
    return pa.FixedSizeListArray.from_arrays(flat, type=float_type(values.shape[-1]))


def transform_lists(offsets: pa.Array, translations: pa.Array, quaternions: pa.Array, parents: pa.Array, children: pa.Array) -> pa.Array:
    """`TRANSFORMS`: each row's transforms, `offsets` into the per-transform columns."""
    structs = pa.StructArray.from_arrays([translations, quaternions, parents, children], fields=list(TRANSFORM))
    return pa.ListArray.from_arrays(offsets, structs, type=TRANSFORMS)


def transform_fields() -> list[tuple[str, ComponentDescriptor]]:
    """Each field of `TRANSFORM` and the Transform3D component it is written as."""
    import rerun as rr

    return [(field.name, getattr(rr.Transform3D, f"descriptor_{field.name}")()) for field in TRANSFORM]


def transform_lenses(
    source: SourceStream,
    batch_entity: str,
    component: str,
    output_entity: str,
    function: Callable[[pa.Array], pa.Array],
    errors: CallbackErrors,
    within: str = "",
) -> tuple[DeriveLens, DeriveLens]:
    """(compute, scatter) for one output entity: `function` maps the source's vectors to per-row transform lists, or
    (`within` a field name) to structs holding that list in the field, beside what other lenses read (joint_series.py)."""
    from rerun.chunk import DeriveLens, Selector

    rows = f".{within}[]" if within else ".[]"
    compute = DeriveLens(source.component, output_entity=batch_entity).to_component(component, Selector(".").pipe(errors.wrap(function)))
    scatter = DeriveLens(component, output_entity=output_entity, scatter=True)
    for name, descriptor in transform_fields():
        scatter = scatter.to_component(descriptor, Selector(f"{rows}.{name}"))
    return compute, scatter


def transform_stream(
    source: SourceStream, pairs: list[tuple[DeriveLens, DeriveLens]], errors: CallbackErrors, also: Sequence[DeriveLens] = ()
) -> LazyChunkStream:
    """One read of the source feeds every pair: all computes on the source's entity, then all scatters (and `also`,
    lenses that read the computes' output too). The source is passed through `errors` so that its own checks'
    errors reach the user as themselves."""
    stream = errors.wrap_stream(source.stream)
    return stream.lenses([compute for compute, _ in pairs], content=source.entity).lenses([*(scatter for _, scatter in pairs), *also])

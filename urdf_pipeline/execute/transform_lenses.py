"""The lens pair behind every derived transform stream (robot FK, temporal edges): compute, then scatter.

The compute lens turns each row of a source's component into one list of {translation, quaternion, parent_frame,
child_frame} structs (the shape Rerun's `compute_joint_transform_batches` returns) on a private entity; the scatter
lens spreads each list into Transform3D rows on the output entity. Both are built here, so the FK and the temporal
edges cannot drift apart.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pyarrow as pa
    from rerun.chunk import DeriveLens, LazyChunkStream

    from ..sources import CallbackErrors, SourceStream


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
    import rerun as rr
    from rerun.chunk import DeriveLens, Selector

    rows = f".{within}[]" if within else ".[]"
    compute = DeriveLens(source.component, output_entity=batch_entity).to_component(component, Selector(".").pipe(errors.wrap(function)))
    scatter = (
        DeriveLens(component, output_entity=output_entity, scatter=True)
        .to_component(rr.Transform3D.descriptor_translation(), Selector(f"{rows}.translation"))
        .to_component(rr.Transform3D.descriptor_quaternion(), Selector(f"{rows}.quaternion"))
        .to_component(rr.Transform3D.descriptor_parent_frame(), Selector(f"{rows}.parent_frame"))
        .to_component(rr.Transform3D.descriptor_child_frame(), Selector(f"{rows}.child_frame"))
    )
    return compute, scatter


def transform_stream(
    source: SourceStream, pairs: list[tuple[DeriveLens, DeriveLens]], errors: CallbackErrors, also: Sequence[DeriveLens] = ()
) -> LazyChunkStream:
    """One read of the source feeds every pair: all computes on the source's entity, then all scatters (and `also`,
    lenses that read the computes' output too). The source is passed through `errors` so that its own checks'
    errors reach the user as themselves."""
    stream = errors.wrap_stream(source.stream)
    return stream.lenses([compute for compute, _ in pairs], content=source.entity).lenses([*(scatter for _, scatter in pairs), *also])

"""Calibration edges as one static Transform3D chunk."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..plan import EdgePlan

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

CALIBRATION_ENTITY = "/calibration"


def calibration_stream(edges: tuple[EdgePlan, ...]) -> LazyChunkStream:
    import rerun as rr
    from rerun.chunk import Chunk, LazyChunkStream

    if not edges:
        return LazyChunkStream.from_iter([])
    chunk = Chunk.from_columns(
        CALIBRATION_ENTITY,
        indexes=[],
        columns=rr.Transform3D.columns(
            translation=[e.translation for e in edges],
            quaternion=[e.quaternion_xyzw for e in edges],
            parent_frame=[e.parent for e in edges],
            child_frame=[e.child for e in edges],
        ),
    )
    return LazyChunkStream.from_iter([chunk])

"""What a recording was made from, stored as static recording properties so two runs can be compared."""

from __future__ import annotations

from typing import TYPE_CHECKING

from . import __version__
from .plan import Plan

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

PROPERTY_NAME = "urdf_pipeline"


def provenance_fields(plan: Plan) -> dict[str, str]:
    fields = {"version": __version__}
    for robot in plan.robots:
        fields[f"{robot.key}_urdf_sha256"] = robot.urdf_sha256
        fields[f"{robot.key}_urdf_origin"] = robot.urdf_origin
    return fields


def provenance_stream(plan: Plan) -> LazyChunkStream:
    import rerun as rr
    from rerun.chunk import Chunk, LazyChunkStream

    values = rr.AnyValues(**provenance_fields(plan))  # type: ignore[arg-type]
    return LazyChunkStream.from_iter([Chunk.from_property(PROPERTY_NAME, values)])

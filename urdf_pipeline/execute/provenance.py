"""What a recording was made from, stored as static recording properties so two runs can be compared."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..package import __version__
from ..plan import ScenePlan

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

PROPERTY_NAME = "urdf_pipeline"
MODEL_PROPERTY_NAME = "urdf_pipeline_model"  # the model asset's own: it never collides with a segment's properties


def _property(parts: str) -> str:
    return MODEL_PROPERTY_NAME if parts == "model" else PROPERTY_NAME


def provenance_stream(plan: ScenePlan, parts: str = "all", extra: dict[str, str] | None = None) -> LazyChunkStream:
    import rerun as rr
    from rerun.chunk import Chunk, LazyChunkStream

    fields = {"version": __version__, **(extra or {})}
    for robot in plan.robots:
        fields[f"{robot.key}_urdf_sha256"] = robot.urdf_sha256
        fields[f"{robot.key}_urdf_origin"] = robot.urdf_origin
    return LazyChunkStream.from_iter([Chunk.from_property(_property(parts), rr.AnyValues(**fields))])  # type: ignore[arg-type]


def stored_content_hash(path: Path, parts: str) -> str | None:
    """The content hash a recording was written with (None if unreadable or written without one)."""
    from rerun.chunk import RrdReader

    try:
        chunks = RrdReader(path).stream().filter(content=f"/__properties/{_property(parts)}").to_chunks()
    except (OSError, ValueError, RuntimeError):
        return None
    for chunk in chunks:
        batch = chunk.to_record_batch()
        for field_name in batch.schema.names:
            if field_name.endswith("content_sha256"):
                value = batch.column(field_name).to_pylist()[0]
                return str(value[0] if isinstance(value, list) else value)
    return None

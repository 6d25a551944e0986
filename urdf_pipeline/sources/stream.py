"""What every source kind hands to the kinematics stage."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream


@dataclass(frozen=True)
class SourceStream:
    """A lazy stream whose `component` on `entity` holds one joint-value vector per row."""

    stream: LazyChunkStream
    entity: str
    component: str
    width: int  # values per row, equal to the number of names

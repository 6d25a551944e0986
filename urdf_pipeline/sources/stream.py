"""What every source kind hands to the kinematics stage."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..plan import IndexPlan

if TYPE_CHECKING:
    from rerun.chunk import IndexColumn, LazyChunkStream


@dataclass(frozen=True)
class SourceStream:
    """A lazy stream whose `component` on `entity` holds one instance per row: a joint-value vector (`width` numbers,
    in the order of the source's names), or, when `named`, a struct mapped by name, row by row (named_rows.py)."""

    stream: LazyChunkStream
    entity: str
    component: str
    width: int  # values per row, equal to the number of names
    named: bool = False


def index_column(index: IndexPlan) -> IndexColumn:
    """The Rerun timeline a reader builds from an index column (parquet column, HDF5 dataset)."""
    from rerun.chunk import IndexColumn

    if index.kind == "sequence":
        return IndexColumn.sequence(index.column)
    if index.kind == "timestamp":
        return IndexColumn.timestamp(index.column, input_unit=index.unit)  # type: ignore[arg-type]
    return IndexColumn.duration(index.column, input_unit=index.unit)  # type: ignore[arg-type]


def compile_index(spec: Any) -> IndexPlan:
    """A config's `index` (a column name, or {sequence|timestamp|duration: COLUMN, unit: U}) as an IndexPlan."""
    if isinstance(spec, str):
        return IndexPlan(spec, "sequence", None)
    if "sequence" in spec:
        return IndexPlan(spec["sequence"], "sequence", None)
    kind = "timestamp" if "timestamp" in spec else "duration"
    return IndexPlan(spec[kind], "timestamp" if kind == "timestamp" else "duration", spec.get("unit", "s"))


def per_row(values: pa.Array) -> pa.ListArray:
    """Each of `values` as a list of its own, one per row: Rerun's lenses hand a selector a row's instances flattened."""
    return pa.ListArray.from_arrays(pa.array(np.arange(len(values) + 1, dtype=np.int32)), values)


def component_field(name: str, column_type: pa.DataType) -> pa.Field:
    """The field of a data column Rerun reads as the component `name`."""
    return pa.field(name, column_type, metadata={b"rerun:kind": b"data", b"rerun:component": name.encode()})


def is_list_type(value_type: pa.DataType) -> bool:
    return bool(pa.types.is_list(value_type) or pa.types.is_large_list(value_type) or pa.types.is_fixed_size_list(value_type))

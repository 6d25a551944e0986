"""Rows that name their own values (ROS JointState messages, recordings with per-row names): map by name, columnar.

A named row is a struct {name: list<string>, position: list<number>}, the order of its names free from row to row.
`named_matrix` turns a batch of them into the matrix a vector source gives, without a Python loop over rows.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..errors import UserError, listing
from ..plan import NamedSource
from .stream import per_row

NAMED_COMPONENT = "urdf_pipeline:named_joint_values"
NAME_FIELD = "name"
VALUE_FIELD = "position"


def is_named_rows(values: pa.Array) -> bool:
    return pa.types.is_struct(values.type)


def named_rows_column(names: pa.Array, values: pa.Array) -> pa.ListArray:
    """Per-row names (list<string>) and values (list<number>) -> a component column holding one struct per row."""
    value_type = pa.large_list(pa.float64()) if pa.types.is_large_list(values.type) else pa.list_(pa.float64())
    struct = pa.StructArray.from_arrays([names, values.cast(value_type)], [NAME_FIELD, VALUE_FIELD])
    return per_row(struct)


def named_matrix(rows: pa.Array, source: NamedSource, required: Sequence[int] | np.ndarray, consumer: str) -> np.ndarray:
    """(rows x len(source.names)) float64 matrix, NaN where a row lacks a name; `required` are the positions the
    `consumer` ("robot 'arm'") reads. Counts in messages are per batch: the run stops at the first batch with a problem."""
    count, width, label = len(rows), len(source.names), f"source '{source.name}'"
    if rows.null_count:
        raise UserError(f"{label} has {rows.null_count} rows without values", source.where)
    names = pc.struct_field(rows, NAME_FIELD)
    values = pc.struct_field(rows, VALUE_FIELD)
    name_lengths = names.value_lengths().fill_null(0).to_numpy(zero_copy_only=False)
    value_lengths = values.value_lengths().fill_null(0).to_numpy(zero_copy_only=False)
    uneven = name_lengths != value_lengths
    if uneven.any():
        first = int(np.argmax(uneven))
        raise UserError(
            f"{label} has rows of {int(value_lengths[first])} values but {int(name_lengths[first])} names "
            f"({int(uneven.sum())} of {count} rows in one batch); every row must give one value per name",
            source.where,
        )
    flat_names = names.flatten()
    flat_values = values.flatten().to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
    position = pc.index_in(flat_names, value_set=pa.array(source.names, pa.string()))
    row_of = np.repeat(np.arange(count, dtype=np.int64), name_lengths)
    unknown = position.is_null().to_numpy(zero_copy_only=False)
    if unknown.any():
        strangers = sorted(pc.unique(flat_names.filter(pa.array(unknown))).to_pylist())
        quoted = listing([f"'{n}'" for n in strangers], limit=8)
        raise UserError(
            f"{label} has rows naming {quoted}, not among its names ({np.unique(row_of[unknown]).size} of {count} rows "
            f"in one batch); list every name the data carries in sources.{source.name}.names and map or ignore it",
            source.where,
        )
    cell = row_of * width + position.to_numpy(zero_copy_only=False).astype(np.int64)
    seen = np.bincount(cell, minlength=count * width).reshape(count, width)
    if (seen > 1).any():
        row, column = np.argwhere(seen > 1)[0]
        raise UserError(
            f"{label} names '{source.names[column]}' {int(seen[row, column])} times in one row "
            f"({int((seen > 1).any(axis=1).sum())} of {count} rows in one batch); a row must name each value once",
            source.where,
        )
    columns = np.unique(np.asarray(required, dtype=np.intp))
    missing = seen[:, columns] == 0
    if missing.any():
        lacking = [(source.names[c], int(n)) for c, n in zip(columns, missing.sum(axis=0), strict=True) if n]
        described = ", ".join(f"'{name}' from {n}" for name, n in lacking)
        raise UserError(
            f"{label} rows lack names that {consumer} maps: {described} of {count} rows in one batch; "
            f"every row must carry each mapped name (for a joint the data lacks, use joints.hold instead of mapping it)",
            source.where,
        )
    matrix = np.full((count, width), np.nan)
    matrix.reshape(-1)[cell] = flat_values
    return matrix

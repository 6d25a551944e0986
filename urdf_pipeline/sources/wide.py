"""Wide tables: one numeric column per name and one index column, the usual shape of exported logs (CSV, parquet).

Compile checks the header alone (a CSV's first block, a parquet footer). Run: the file comes in bounded batches, each
made, column by column with numpy, into chunks of BLOCK_ROWS rows holding one joint vector per row, the stream every
other kind gives; no row is ever looked at on its own in Python.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..config import Document
from ..errors import UserError, Where, did_you_mean, listing
from ..plan import IndexPlan
from .base import EntryField, SourceDescription, shown_file
from .lerobot import VECTOR_COMPONENT
from .ordering import BLOCK_ROWS, in_time_order
from .stream import SourceStream, compile_index, component_field, is_list_type, per_row
from .time_range import index_problem

if TYPE_CHECKING:
    from rerun.chunk import Chunk

    from ..plan import CsvSourcePlan, ParquetSourcePlan

    WidePlan = CsvSourcePlan | ParquetSourcePlan

TIME_FACTORS = {"s": 1_000_000_000, "ms": 1_000_000, "us": 1_000, "ns": 1}  # to Rerun's nanoseconds
_SEQUENCE_COLUMNS = ("frame_index", "index", "frame", "step", "seq", "sequence")  # what `init` takes for a timeline
_TIME_COLUMNS = ("timestamp", "time", "t", "stamp", "time_s", "timestamp_s", "sec", "seconds")


def _is_number(value_type: pa.DataType) -> bool:
    """A value column: integers, floats or decimals; `null` is a CSV column empty in its first block (NaN so far)."""
    return bool(
        pa.types.is_integer(value_type)
        or pa.types.is_floating(value_type)
        or pa.types.is_decimal(value_type)
        or pa.types.is_null(value_type)
    )


def index_type_problem(column: str, value_type: pa.DataType, kind: str) -> str | None:
    """Why an index column of this type cannot be the timeline, or None."""
    if kind == "sequence" and not pa.types.is_integer(value_type):
        return (
            f"index column '{column}' is {value_type}; a sequence timeline needs integers (use {{timestamp: {column}, unit: s}} for times)"
        )
    if kind != "sequence" and not (
        pa.types.is_integer(value_type) or pa.types.is_floating(value_type) or pa.types.is_timestamp(value_type)
    ):
        return f"index column '{column}' is {value_type}, not a time"
    return None


def wide_columns(
    spec: dict[str, Any], kind: str, file: Path, schema: pa.Schema, document: Document, here: tuple[str, str]
) -> tuple[IndexPlan, tuple[str, ...]]:
    """The index and the value columns of a wide table, checked against its header: the config's `names` (each a
    column), else every column but the index. Refused: a missing column, a non-numeric value column, an index that
    cannot be the timeline, a used column named twice or without a name."""
    index = compile_index(spec["index"])
    columns = list(schema.names)
    places = _Places(document, here, kind, given="names" in spec)
    if index.column not in columns:
        raise UserError(
            f"index column '{index.column}' not among the columns of {file.name}{did_you_mean(index.column, columns)}; "
            f"its columns: {listing(columns)}",
            places.index(),
        )
    names = tuple(spec["names"]) if places.given else tuple(c for c in columns if c != index.column)
    _check_value_names(names, index.column, columns, file, places)
    if not names:
        raise UserError(f"{file.name} has no column but the index '{index.column}': no joint values", places.source())
    _check_header(index.column, names, columns, file, places)
    problem = index_type_problem(index.column, schema.field(index.column).type, index.kind)
    if problem is not None:
        raise UserError(problem, places.index())
    _check_numbers(names, schema, file, places)
    return index, names


@dataclass(frozen=True)
class _Places:
    """Where a wide table's problems point: its index key; a value column's `names` entry when the config lists them,
    else the source's file key (the value columns came from the header)."""

    document: Document
    here: tuple[str, str]
    kind: str
    given: bool  # the config lists the value columns in `names`

    def index(self) -> Where:
        return self.document.where(*self.here, "index")

    def source(self) -> Where:
        return self.document.where(*self.here, self.kind)

    def name(self, position: int) -> Where:
        return self.document.where(*self.here, "names", position) if self.given else self.source()


def _check_value_names(names: tuple[str, ...], index_column: str, columns: list[str], file: Path, places: _Places) -> None:
    """Each value name is a column of the header, and not the index column (a value and its time in one cell)."""
    for position, name in enumerate(names):
        if name not in columns:
            raise UserError(
                f"column '{name}' not among the columns of {file.name}{did_you_mean(name, columns)}; its columns: {listing(columns)}",
                places.name(position),
            )
        if name == index_column:
            raise UserError(f"'{name}' is the index column; names lists the value columns only", places.name(position))


def _check_header(index_column: str, names: tuple[str, ...], columns: list[str], file: Path, places: _Places) -> None:
    """Every column used is named once in the header: a column read by name must be the one the config means."""
    for name in (index_column, *names):
        count = columns.count(name)
        where = places.index() if name == index_column else places.source()
        if not name:
            raise UserError(
                f"column {columns.index(name) + 1} of {file.name} has no name in the header; name it, or list the value columns in names:",
                where,
            )
        if count > 1:
            raise UserError(
                f"the header of {file.name} names column '{name}' {count} times; a wide table's columns need distinct names", where
            )


def _check_numbers(names: tuple[str, ...], schema: pa.Schema, file: Path, places: _Places) -> None:
    """Every value column holds numbers (one per cell); a list column in parquet is pointed at `column:`."""
    for position, name in enumerate(names):
        value_type = schema.field(name).type
        if not _is_number(value_type):
            hint = "" if places.given else "; list the value columns in names: to leave it out"
            if is_list_type(value_type):
                hint += f" (or give column: {name} if it holds all the values of a row)" if places.kind == "parquet" else ""
            raise UserError(
                f"column '{name}' of {file.name} is {value_type}, not numbers: a wide table holds one number per cell{hint}",
                places.name(position),
            )


def timeline(values: pa.Array, index: IndexPlan, first_row: int, plan: WidePlan) -> pa.Array:
    """One batch's index column as Rerun's index array: int64 (a sequence), timestamp[ns] or duration[ns]. An empty
    cell, or a value whose timeline value does not fit int64 (time_range.py), is refused naming its row."""
    problem = index_problem(values, index, first_row, f"index column '{index.column}' of {plan.path}")
    if problem is not None:
        raise UserError(problem, plan.where)
    if index.kind == "sequence":
        return values.cast(pa.int64())
    if pa.types.is_timestamp(values.type):  # already a time: its own unit, not the config's
        ints = np.asarray(values.cast(pa.timestamp("ns", values.type.tz)).cast(pa.int64()).to_numpy(zero_copy_only=False), dtype=np.int64)
    else:
        factor = TIME_FACTORS[index.unit or "s"]
        raw = values.to_numpy(zero_copy_only=False)
        if pa.types.is_integer(values.type):
            ints = raw.astype(np.int64) * factor  # fits: checked above
        else:
            ints = np.round(raw.astype(np.float64) * factor).astype(np.int64)  # as Rerun's readers round
    arrow_type = pa.timestamp("ns") if index.kind == "timestamp" else pa.duration("ns")
    return pa.array(ints, pa.int64()).cast(arrow_type)


def value_matrix(batch: pa.RecordBatch, names: Sequence[str]) -> np.ndarray:
    """(rows x names) float64, one whole column at a time; empty cells are NaN (the NaN policy decides)."""
    matrix = np.empty((batch.num_rows, len(names)), dtype=np.float64)
    for position, name in enumerate(names):  # one iteration per column, never per row
        matrix[:, position] = batch.column(name).cast(pa.float64()).to_numpy(zero_copy_only=False)
    return matrix


def _chunk_fields(index: IndexPlan, index_type: pa.DataType, vectors: pa.DataType, entity: str) -> pa.Schema:
    return pa.schema(
        [
            pa.field(index.column, index_type, metadata={b"rerun:kind": b"index", b"rerun:index_name": index.column.encode()}),
            component_field(VECTOR_COMPONENT, vectors),
        ],
        metadata={b"rerun:entity_path": entity.encode()},
    )


def vector_chunks(batches: Iterator[pa.RecordBatch], plan: WidePlan, entity: str) -> Iterator[Chunk]:
    """Each batch of the file as chunks of at most BLOCK_ROWS rows, one vector of len(names) values per row; each
    chunk gets arrays of its own (a slice of one large list array costs Rerun's FK as much as the whole array)."""
    from rerun.chunk import Chunk

    width, rows_before = len(plan.names), 0
    for batch in batches:  # one iteration per batch of the file
        index_array = timeline(batch.column(plan.index.column), plan.index, rows_before, plan)
        matrix = value_matrix(batch, plan.names)
        for start in range(0, batch.num_rows, BLOCK_ROWS):  # one iteration per block of rows
            block = np.ascontiguousarray(matrix[start : start + BLOCK_ROWS])
            rows = len(block)
            inner = pa.ListArray.from_arrays(pa.array(np.arange(0, rows * width + 1, width, dtype=np.int32)), pa.array(block.reshape(-1)))
            vectors = per_row(inner)
            times = index_array.slice(start, rows)
            schema = _chunk_fields(plan.index, times.type, vectors.type, entity)
            yield from Chunk.from_record_batch(pa.RecordBatch.from_arrays([pa.concat_arrays([times]), vectors], schema=schema))
        rows_before += batch.num_rows


def wide_stream(plan: WidePlan, batches: Callable[[], Iterator[pa.RecordBatch]]) -> SourceStream:
    """The lazy stream of a wide table: `batches()` is called when the stream is first read."""
    from rerun.chunk import LazyChunkStream

    entity = f"/{plan.name}"

    def chunks() -> Iterator[Chunk]:
        yield from vector_chunks(batches(), plan, entity)

    stream = in_time_order(LazyChunkStream.from_iter(chunks()), plan.index.column, plan, shown_file(plan))
    return SourceStream(stream, entity, VECTOR_COMPONENT, len(plan.names))


def reading_error(path: Path | str, exc: BaseException, header: Sequence[str], where: Where | None) -> UserError:
    """pyarrow's reading or conversion error as one line naming the file, and the column by its name (pyarrow's CSV
    reader numbers it in the header, from 0) and the line (its "Row #N" counts the header's line too)."""
    reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    column = re.search(r"In CSV column #(\d+): ", reason)
    if column is not None and int(column.group(1)) < len(header):
        reason = reason.replace(column.group(0), f"column '{header[int(column.group(1))]}': ")
    reason = re.sub(r"Row #(\d+)", r"line \1", reason)
    return UserError(f"cannot read {path}: {reason}", where)


def guess_index(schema: pa.Schema, file_name: str) -> EntryField:
    """For `init`: the timeline column, a sequence column by its name, else a time column, else a stub to fill in."""
    integers = [n for n in schema.names if pa.types.is_integer(schema.field(n).type)]
    times = [
        n
        for n in schema.names
        if pa.types.is_timestamp(schema.field(n).type) or (pa.types.is_floating(schema.field(n).type) and n.lower() in _TIME_COLUMNS)
    ]
    sequence = next((n for n in _SEQUENCE_COLUMNS if n in integers), None)
    if sequence is not None:
        return EntryField("index", sequence, "review: the timeline column (a sequence); or {timestamp: COL, unit: s}")
    if times:
        return EntryField(
            "index", {"timestamp": times[0], "unit": "s"}, "review: time since the epoch; {duration: COL, unit: s} if it counts from 0"
        )
    return EntryField("index", "frame_index", f"TODO: {file_name} has no frame or time column this could guess; name its timeline column")


def describe_wide(kind: str, schema: pa.Schema, file: Path, segment: str, pattern: bool) -> SourceDescription:
    """For `init`: a wide table's names are its numeric columns but the guessed index; columns left out (text, lists)
    are named in an explicit `names` entry, so that the config validates as written."""
    index = guess_index(schema, file.name)
    column = index.value["timestamp"] if isinstance(index.value, dict) else index.value
    values = [n for n in schema.names if n != column and n]
    numeric = tuple(n for n in values if _is_number(schema.field(n).type) and schema.names.count(n) == 1)
    if not numeric:
        raise UserError(f"{file.name} has no numeric column but the index: not a wide table of joint values")
    fields: tuple[EntryField, ...] = (index,)
    left_out = [n or "(unnamed)" for n in schema.names if n != column and n not in numeric]
    if left_out:
        fields += (EntryField("names", list(numeric), f"the numeric columns; left out: {listing(left_out)}"),)
    return SourceDescription(kind, fields, numeric, None, segment, pattern=pattern)

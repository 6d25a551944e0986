"""A parquet file with one row per frame and a list<float> column of joint values."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..config import Document
from ..errors import UserError, listing
from ..plan import IndexPlan, ParquetSourcePlan
from .base import EntryField, SourceDescription, file_input, resolve_input
from .integrity import check_parquet_pages, refuse_empty_parquet
from .ordering import in_time_order, with_duplicates
from .stream import SourceStream

PLAN_TYPE = ParquetSourcePlan
SPEC_FORM = "parquet:FILE[#COLUMN]"
SUFFIXES = (".parquet",)
_SEQUENCE_COLUMNS = ("frame_index", "index", "frame", "step", "seq", "sequence")  # what `init` takes for a timeline
_TIME_COLUMNS = ("timestamp", "time", "t", "stamp")


def compile_index(spec: Any) -> IndexPlan:
    if isinstance(spec, str):
        return IndexPlan(spec, "sequence", None)
    if "sequence" in spec:
        return IndexPlan(spec["sequence"], "sequence", None)
    kind = "timestamp" if "timestamp" in spec else "duration"
    return IndexPlan(spec[kind], "timestamp" if kind == "timestamp" else "duration", spec.get("unit", "s"))


def _numeric_list_width(field_type: pa.DataType) -> int | None | bool:
    """None for a variable-length numeric list, the width of a fixed-size one, False if not a numeric list."""
    if pa.types.is_fixed_size_list(field_type) or pa.types.is_list(field_type) or pa.types.is_large_list(field_type):
        value_type = field_type.value_type
        if not (pa.types.is_floating(value_type) or pa.types.is_integer(value_type)):
            return False
        return field_type.list_size if pa.types.is_fixed_size_list(field_type) else None
    return False


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> ParquetSourcePlan:
    here = ("sources", name)
    path = resolve_input(document, config_dir, spec["parquet"], *here, "parquet")
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"cannot read parquet schema of {path}: {exc}", document.where(*here, "parquet")) from None
    column = spec["column"]
    if column not in schema.names:
        raise UserError(f"column '{column}' not in {path.name}; it has: {', '.join(schema.names)}", document.where(*here, "column"))
    width = _numeric_list_width(schema.field(column).type)
    if width is False:
        raise UserError(
            f"column '{column}' is {schema.field(column).type}, not a list of numbers (one value per joint name)",
            document.where(*here, "column"),
        )
    names = tuple(spec["names"])
    if width is not None and width != len(names):
        raise UserError(f"column '{column}' holds {width} values per row but {len(names)} names are given", document.where(*here, "names"))
    index = compile_index(spec["index"])
    if index.column not in schema.names:
        raise UserError(
            f"index column '{index.column}' not in {path.name}; it has: {', '.join(schema.names)}", document.where(*here, "index")
        )
    index_type = schema.field(index.column).type
    if index.kind == "sequence" and not pa.types.is_integer(index_type):
        raise UserError(
            f"index column '{index.column}' is {index_type}; a sequence timeline needs integers (use {{timestamp: {index.column}, unit: s}} for times)",
            document.where(*here, "index"),
        )
    if index.kind != "sequence" and not (
        pa.types.is_integer(index_type) or pa.types.is_floating(index_type) or pa.types.is_timestamp(index_type)
    ):
        raise UserError(f"index column '{index.column}' is {index_type}, not a time", document.where(*here, "index"))
    refuse_empty_parquet(path, document.where(*here, "parquet"))  # from the footer, before any data page
    check_parquet_pages(path, [column, index.column], document.where(*here, "parquet"))  # corrupt pages: a user error here
    return with_duplicates(ParquetSourcePlan(name, path, column, index, names, document.where(*here)), spec)


def open_stream(plan: ParquetSourcePlan) -> SourceStream:
    from rerun.chunk import IndexColumn
    from rerun.experimental import ParquetReader

    index = plan.index
    if index.kind == "sequence":
        index_column = IndexColumn.sequence(index.column)
    elif index.kind == "timestamp":
        index_column = IndexColumn.timestamp(index.column, input_unit=index.unit)  # type: ignore[arg-type]
    else:
        index_column = IndexColumn.duration(index.column, input_unit=index.unit)  # type: ignore[arg-type]
    entity = f"/{plan.column}"
    stream = ParquetReader(plan.path).stream(index_columns=[index_column], column_grouping="individual").filter(content=entity)
    stream = in_time_order(stream, index.column, plan, plan.path)
    return SourceStream(stream, entity, plan.column, len(plan.names))


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the column (PART, else `observation.state`, else the only list column) and a guessed timeline,
    from the schema only. Parquet has no names: the values are matched by position."""
    given = file_input(path)
    file = given.file
    try:
        schema = pq.read_schema(file)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"cannot read the parquet schema of {file}: {exc}") from None
    lists = [column for column in schema.names if _numeric_list_width(schema.field(column).type) is not False]
    if part is not None:
        column = part
    elif "observation.state" in lists:
        column = "observation.state"
    elif len(lists) == 1:
        column = lists[0]
    else:
        raise UserError(f"name the column with parquet:FILE#COLUMN; list columns of {file.name}: {listing(lists, empty='none')}")
    if column not in schema.names:
        raise UserError(f"column '{column}' not in {file.name}; it has: {', '.join(schema.names)}")
    width = _numeric_list_width(schema.field(column).type)
    if width is False:
        raise UserError(f"column '{column}' is {schema.field(column).type}, not a list of numbers")
    fields = (EntryField("column", column), _guess_index(schema, file.name))
    return SourceDescription(
        "parquet",
        fields,
        None,
        width if isinstance(width, int) else None,
        given.segment,
        pattern=given.pattern,
        unnamed="parquet carries no names",
    )


def _guess_index(schema: pa.Schema, file_name: str) -> EntryField:
    """The timeline column: a sequence column by its name, else a time column, else a stub to fill in."""
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

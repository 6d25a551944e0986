"""A parquet file with one row per frame: a list<float> column of joint values (read with Rerun's ParquetReader), or a
wide table, one numeric column per name (no `column` in the config; read with pyarrow batch by batch, see wide.py)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..config import Document
from ..errors import UserError, Where, listing
from ..plan import ParquetSourcePlan
from ..remote import is_remote
from .base import EntryField, SourceDescription, file_input, resolve_input, shown_file
from .integrity import check_parquet_pages, refuse_empty_parquet
from .ordering import in_time_order, with_duplicates
from .stream import SourceStream, compile_index, index_column, is_list_type
from .time_range import check_parquet_index
from .wide import describe_wide, guess_index, index_type_problem, reading_error, wide_columns, wide_stream

PLAN_TYPE = ParquetSourcePlan
SPEC_FORM = "parquet:FILE[#COLUMN]"
SUFFIXES = (".parquet",)
PARQUET_BATCH_ROWS = 65_536  # rows decoded at a time from a wide table (a row group may hold a million)


def _numeric_list_width(field_type: pa.DataType) -> int | None | bool:
    """None for a variable-length numeric list, the width of a fixed-size one, False if not a numeric list."""
    if is_list_type(field_type):
        value_type = field_type.value_type
        if not (pa.types.is_floating(value_type) or pa.types.is_integer(value_type)):
            return False
        return field_type.list_size if pa.types.is_fixed_size_list(field_type) else None
    return False


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> ParquetSourcePlan:
    here = ("sources", name)
    if is_remote(spec["parquet"]):
        return _compile_remote(name, spec, document)
    path = resolve_input(document, config_dir, spec["parquet"], *here, "parquet")
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"cannot read parquet schema of {path}: {exc}", document.where(*here, "parquet")) from None
    plan = _checked(name, spec, document, path, path.name, schema)
    refuse_empty_parquet(path, document.where(*here, "parquet"))  # from the footer, before any data page
    _check_data(plan, document.where(*here, "parquet"), document.where(*here, "index"))
    return plan


def _compile_remote(name: str, spec: dict[str, Any], document: Document) -> ParquetSourcePlan:
    """`parquet: s3://BUCKET/KEY`: the object's ETag and footer only (ranged GETs), never its data pages; those are
    checked when `run` has downloaded it (`check_download`)."""
    from ..remote import cached_metadata, cached_path, open_range, remote_file

    where = document.where("sources", name, "parquet")
    remote = remote_file(spec["parquet"], where, "parquet file")

    def footer(target: Path) -> None:  # the footer alone, as a parquet metadata file (kept per ETag)
        with open_range(remote, where) as reader:
            pq.read_metadata(reader).write_metadata_file(str(target))

    try:
        with cached_metadata(remote, "footer", footer) as path:
            metadata = pq.read_metadata(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"cannot read the parquet footer of {remote.url}: {exc}", where) from None
    plan = _checked(name, spec, document, cached_path(remote), remote.url.rsplit("/", 1)[-1], metadata.schema.to_arrow_schema())
    if metadata.num_rows == 0:
        raise UserError(f"parquet file {remote.url} has zero rows (its footer says so); a source with zero rows moves nothing", where)
    return replace(plan, remote=remote)


def _checked(name: str, spec: dict[str, Any], document: Document, path: Path, shown_name: str, schema: pa.Schema) -> ParquetSourcePlan:
    """The plan, from the schema alone: the column and index exist and have types that fit."""
    here = ("sources", name)
    if "column" not in spec:  # a wide table: checked from the footer alone; pyarrow reads it (no page check needed)
        index, names = wide_columns(spec, "parquet", Path(shown_name), schema, document, here)
        return with_duplicates(ParquetSourcePlan(name, path, None, index, names, document.where(*here)), spec)
    column = spec["column"]
    if column not in schema.names:
        raise UserError(f"column '{column}' not in {shown_name}; it has: {', '.join(schema.names)}", document.where(*here, "column"))
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
            f"index column '{index.column}' not in {shown_name}; it has: {', '.join(schema.names)}", document.where(*here, "index")
        )
    problem = index_type_problem(index.column, schema.field(index.column).type, index.kind)
    if problem is not None:
        raise UserError(problem, document.where(*here, "index"))
    return with_duplicates(ParquetSourcePlan(name, path, column, index, names, document.where(*here)), spec)


def _check_data(plan: ParquetSourcePlan, where: Where, index_where: Where) -> None:
    """What only the data pages tell: they decode, and the index values fit a timeline."""
    if plan.column is None:
        check_parquet_index(plan.path, plan.index, index_where)  # the index column alone: times that fit
    else:
        # corrupt pages: a user error here; in the same pass, index values beyond int64 ns (Rerun's reader would wrap them)
        check_parquet_pages(plan.path, [plan.column, plan.index.column], where, plan.index, index_where)


def check_download(plan: ParquetSourcePlan) -> None:
    """A remote file's data checks, once `run` has downloaded it to `plan.path` (compile read its footer only)."""
    _check_data(plan, plan.where, plan.where)


def _batches(plan: ParquetSourcePlan) -> Iterator[pa.RecordBatch]:
    """A wide table's index and value columns, PARQUET_BATCH_ROWS rows at a time, row group by row group."""
    columns = [plan.index.column, *plan.names]
    try:
        file = pq.ParquetFile(plan.path)
        yield from file.iter_batches(batch_size=PARQUET_BATCH_ROWS, columns=columns)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise reading_error(plan.path, exc, columns, plan.where) from None


def open_stream(plan: ParquetSourcePlan) -> SourceStream:
    from rerun.experimental import ParquetReader

    if plan.column is None:
        return wide_stream(plan, lambda: _batches(plan))
    entity = f"/{plan.column}"
    stream = ParquetReader(plan.path).stream(index_columns=[index_column(plan.index)], column_grouping="individual").filter(content=entity)
    stream = in_time_order(stream, plan.index.column, plan, shown_file(plan))
    return SourceStream(stream, entity, plan.column, len(plan.names))


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the column (PART, else `observation.state`, else the only list column) and a guessed timeline,
    from the schema only. Parquet has no names: the values are matched by position. A file without a list column
    is a wide table: its numeric columns are the names."""
    given = file_input(path)
    file = given.file
    try:
        schema = pq.read_schema(file)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"cannot read the parquet schema of {file}: {exc}") from None
    lists = [column for column in schema.names if _numeric_list_width(schema.field(column).type) is not False]
    if part is None and not lists:  # no list column: a wide table, one column per name
        return describe_wide("parquet", schema, file, given.segment, given.pattern)
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
    fields = (EntryField("column", column), guess_index(schema, file.name))
    return SourceDescription(
        "parquet",
        fields,
        None,
        width if isinstance(width, int) else None,
        given.segment,
        pattern=given.pattern,
        unnamed="parquet carries no names",
    )

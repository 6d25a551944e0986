"""A CSV file with a header, read as a wide table (wide.py) with pyarrow's streaming reader, CSV_BLOCK_BYTES at a time,
never the whole file. pyarrow infers the columns' types from the first block, so validation reads that block only (of
a remote file, one ranged GET); at run time the value columns are read as float64 whatever it suggested, and a bad
cell or row further down stops the run with one error naming the file and the column or row.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.csv as pa_csv

from ..config import Document
from ..errors import UserError, Where
from ..plan import CsvSourcePlan, RemoteObject
from ..remote import is_remote
from .base import SourceDescription, file_input, resolve_input, shown_file
from .ordering import with_duplicates
from .stream import SourceStream
from .time_range import index_problem
from .wide import describe_wide, reading_error, wide_columns, wide_stream

PLAN_TYPE = CsvSourcePlan
SPEC_FORM = "csv:FILE"
SUFFIXES = (".csv",)
CSV_BLOCK_BYTES = 1 << 20  # bytes parsed at a time (pyarrow's default): about 10k rows of a 7-joint log


def _open(
    source: Path | pa.NativeFile, shown: str | Path, where: Where | None, convert: pa_csv.ConvertOptions | None = None
) -> pa_csv.CSVStreamingReader:
    """The streaming reader; opening it parses the first block (types are inferred from it). `shown` names the file
    in messages (its path, or its URL when `source` holds a remote file's first block)."""
    try:
        return pa_csv.open_csv(
            source, read_options=pa_csv.ReadOptions(block_size=CSV_BLOCK_BYTES, use_threads=False), convert_options=convert
        )
    except (pa.ArrowException, OSError, ValueError) as exc:
        if "Empty CSV file" in str(exc):
            raise UserError(f"CSV file {shown} is empty: no header, no rows", where) from None
        raise reading_error(shown, exc, [], where) from None


def _header(source: Path | pa.NativeFile, shown: str | Path, where: Where | None) -> tuple[pa.Schema, pa.RecordBatch]:
    """The header's columns with the types of the first block, which must hold at least one row, and that block."""
    reader = _open(source, shown, where)
    try:
        first = reader.read_next_batch()
    except StopIteration:
        first = None
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise reading_error(shown, exc, [], where) from None
    if first is None or first.num_rows == 0:
        raise UserError(f"CSV file {shown} has a header but no rows; a source with zero rows moves nothing", where)
    return reader.schema, first


def _first_block(remote: RemoteObject, where: Where) -> pa.NativeFile:
    """`csv: s3://BUCKET/KEY`: its first CSV_BLOCK_BYTES bytes (one ranged GET: what pyarrow parses first of a local
    file), cut after their last whole line."""
    from ..remote import open_range

    with open_range(remote, where, block=CSV_BLOCK_BYTES, max_requests=1) as reader:
        data = reader.read(min(remote.size, CSV_BLOCK_BYTES))
    if remote.size > len(data):  # a line cut by the block's end is left for the run, which reads it whole
        end = data.rfind(b"\n")
        if end < 0:
            raise UserError(
                f"the first line of CSV file {remote.url} is longer than {CSV_BLOCK_BYTES} bytes: no header fits a block", where
            )
        data = data[: end + 1]
    return pa.BufferReader(data)


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> CsvSourcePlan:
    here = ("sources", name)
    where = document.where(*here, "csv")
    source: Path | pa.NativeFile
    remote: RemoteObject | None = None
    if is_remote(spec["csv"]):
        from ..remote import cached_path, remote_file

        remote = remote_file(spec["csv"], where, "csv file")
        source, shown, path = _first_block(remote, where), remote.url, cached_path(remote)
    else:
        path = resolve_input(document, config_dir, spec["csv"], *here, "csv")
        source, shown = path, str(path)
    schema, first = _header(source, shown, where)
    index, names = wide_columns(spec, "csv", Path(shown.rsplit("/", 1)[-1]), schema, document, here)
    # The first block's times (the rest are checked as they are read, at run): a wrong unit shows in the first rows.
    problem = index_problem(first.column(index.column), index, 0, f"index column '{index.column}' of {shown}")
    if problem is not None:
        raise UserError(problem, document.where(*here, "index"))
    plan = with_duplicates(CsvSourcePlan(name, path, index, names, document.where(*here)), spec)
    return plan if remote is None else replace(plan, remote=remote)


def check_download(plan: CsvSourcePlan) -> None:
    """Nothing more once `run` has downloaded a remote CSV file: compile checked its first block as it checks a local
    file's, and every later block is checked as the run reads it."""


def _batches(plan: CsvSourcePlan) -> Iterator[pa.RecordBatch]:
    """The index and value columns, block by block; the values as float64 (empty cells and NaN are nulls)."""
    columns = [plan.index.column, *plan.names]
    convert = pa_csv.ConvertOptions(include_columns=columns, column_types=dict.fromkeys(plan.names, pa.float64()))
    shown = shown_file(plan)
    reader = _open(plan.path, shown, plan.where, convert)
    try:
        yield from reader
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise reading_error(shown, exc, _open(plan.path, shown, plan.where).schema.names, plan.where) from None


def open_stream(plan: CsvSourcePlan) -> SourceStream:
    return wide_stream(plan, lambda: _batches(plan))


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the header's numeric columns are the names, and a guessed timeline, from the first block only."""
    given = file_input(path)
    if part is not None:
        raise UserError(f"a CSV source takes no #PART: its columns are the names (the form is {SPEC_FORM})")
    return describe_wide("csv", _header(given.file, given.file, None)[0], given.file, given.segment, given.pattern)

"""One pose per time: a source's rows are checked on their timeline before the kinematics see them.

Two rows with the same index value would be two poses at one time (which one the viewer shows is an accident of
row ids), so they are an error naming the file, the value and both row numbers, unless the source says
`duplicates: keep_last` (the later row in the file wins). Rows out of order are sorted, stably, with one note:
hold_last and the row numbers in later messages then follow time order. Everything is done on whole columns; the
source's rows (only the joint-value component of one entity) are held until the check is done.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..errors import UserError, Where

if TYPE_CHECKING:
    from rerun.chunk import Chunk, LazyChunkStream

DUPLICATE_POLICIES = ("error", "keep_last")
ROW_ID = "rerun.controls.RowId"
BLOCK_ROWS = 4096  # rows per rebuilt chunk: Rerun's FK is fastest in 1k-10k row batches


def duplicates_policy(plan: Any) -> str:
    """The source's `duplicates:` setting (`error` unless the plan carries another)."""
    return str(getattr(plan, "duplicates", "error"))


def _index_values(batch: pa.RecordBatch, timeline: str) -> np.ndarray | None:
    position = batch.schema.get_field_index(timeline)
    if position < 0:
        return None
    column = batch.column(position)
    if not (pa.types.is_integer(column.type) or pa.types.is_timestamp(column.type) or pa.types.is_duration(column.type)):
        return None
    return np.asarray(column.cast(pa.int64()).to_numpy(zero_copy_only=False))


def _rebuilt(batches: list[pa.RecordBatch], rows: np.ndarray) -> Iterator[Chunk]:
    """The rows in the given order, as new chunks (fresh row ids, so the row order is the time order)."""
    from rerun.chunk import Chunk

    metadata = {k: v for k, v in (batches[0].schema.metadata or {}).items() if k != b"rerun:id"}
    stripped = [b.drop_columns([ROW_ID]) if ROW_ID in b.schema.names else b for b in batches]
    table = pa.Table.from_batches([b.replace_schema_metadata(metadata) for b in stripped])
    for start in range(0, len(rows), BLOCK_ROWS):  # one iteration per block of rows
        block = table.take(pa.array(rows[start : start + BLOCK_ROWS])).combine_chunks()
        for batch in block.to_batches():
            yield from Chunk.from_record_batch(batch.replace_schema_metadata(metadata))


def _first_timeline(batch: pa.RecordBatch) -> str:
    """A recording's rows may sit on several timelines; the first index column of the first chunk is checked."""
    kinds = [(field.name, (field.metadata or {}).get(b"rerun:kind")) for field in batch.schema]
    return next((name for name, kind in kinds if kind == b"index"), "")


def _check(chunks: list[Chunk], timeline: str | None, policy: str, label: str, path: Path, where: Where | None) -> Iterator[Chunk]:
    batches = [chunk.to_record_batch() for chunk in chunks]
    if timeline is None:
        timeline = _first_timeline(batches[0]) if batches else ""
    columns = [_index_values(batch, timeline) for batch in batches]
    if not batches or any(values is None for values in columns):  # no such timeline (a generated one): nothing to check
        yield from chunks
        return
    values = np.concatenate([v for v in columns if v is not None])
    if len(values) < 2 or bool(np.all(np.diff(values) > 0)):
        yield from chunks  # the common case: strictly increasing, passed through untouched
        return
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    repeated = ordered[1:] == ordered[:-1]
    if repeated.any():
        first = int(np.argmax(repeated))
        rows = np.sort(order[ordered == ordered[first]])
        shown = ", ".join(str(int(r)) for r in rows[:4]) + (f" and {len(rows) - 4} more" if len(rows) > 4 else "")
        if policy != "keep_last":
            raise UserError(
                f"{label}: {path} has {int(repeated.sum())} rows whose {timeline} repeats an earlier row's; the first: "
                f"{timeline} = {int(ordered[first])} at rows {shown} (counting from 0): two poses at one time. "
                f"Remove the duplicates, or set duplicates: keep_last on the source to keep the last row of each",
                where,
            )
        keep = np.append(~repeated, True)  # the last of each run of equal values is the file's last row with it
        order = order[keep]
        _note(
            f"{label}: {int(repeated.sum())} rows of {path.name} repeat a {timeline} value; kept the last of each (duplicates: keep_last)"
        )
    if bool(np.any(np.diff(values) < 0)):
        moved = int(np.count_nonzero(order != np.arange(len(order)))) if len(order) == len(values) else len(order)
        _note(f"{label}: rows of {path.name} are out of {timeline} order ({moved} rows moved); sorted by {timeline}, stably")
    yield from _rebuilt(batches, order)


def _note(text: str) -> None:
    print(f"note: {text}", file=sys.stderr)


def read_all(stream: LazyChunkStream, path: Path, where: Where | None) -> list[Chunk]:
    """Every chunk of `stream`; a reader's decoding error (a corrupt chunk) becomes a user error naming the file."""
    try:
        return list(stream)
    except (RuntimeError, ValueError, OSError) as exc:
        for cause in (exc.__cause__, exc.__context__):
            if isinstance(cause, UserError):  # raised by one of our own callbacks: keep it
                raise cause from None
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise UserError(f"cannot read {path}, it is probably corrupt: {reason}", where) from None


def in_time_order(stream: LazyChunkStream, timeline: str | None, plan: Any, path: Path) -> LazyChunkStream:
    """`stream` (temporal chunks of the values' entity) checked for repeated index values and sorted on `timeline`
    (None: the recording's first timeline)."""
    from rerun.chunk import LazyChunkStream

    label = f"source '{plan.name}'"

    def checked() -> Iterator[Chunk]:
        yield from _check(read_all(stream, path, plan.where), timeline, duplicates_policy(plan), label, path, plan.where)

    return LazyChunkStream.from_iter(checked())


def with_duplicates(plan: Any, spec: dict[str, Any]) -> Any:
    """The plan with the source's `duplicates:` policy."""
    from dataclasses import replace

    return replace(plan, duplicates=spec.get("duplicates", "error"))

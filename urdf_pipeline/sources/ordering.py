"""One pose per time: a source's rows are checked on their timeline before the kinematics see them (the rule, and
`duplicates: keep_last`: docs/sources.md).

The check streams, so that memory does not grow with the recording: rows in time order (the common case) are passed
on as they come, one chunk at a time; `keep_last` holds one chunk back (a run of equal values may cross into the
next chunk), and a repeat under `error` stops the passing on and reads only the index values to the end, to count
every repeat. Rows out of order cannot be sorted once earlier ones are gone: the stream raises `NeedsSorting`, and
the caller runs again with that source read whole and sorted (`with_sorting_retry`, `sorted_in_memory`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import pyarrow as pa

from ..errors import UserError, Where
from ..logs import note

if TYPE_CHECKING:
    from rerun.chunk import Chunk, LazyChunkStream

ROW_ID = "rerun.controls.RowId"
BLOCK_ROWS = 2048  # rows per joined or rebuilt chunk: Rerun's FK is fastest in 1k-10k row batches, and a block
# becomes one FK chunk of the recording (2048 x up to 32 joints stays under OBJECT_STORE's 65,536 rows)
EVERY_SOURCE = "*"

T = TypeVar("T")

# The sources (by name) that `in_time_order` reads whole; read when a stream is opened, in the opener's context.
_READ_WHOLE: ContextVar[frozenset[str]] = ContextVar("urdf_pipeline_read_whole", default=frozenset())


class NeedsSorting(Exception):
    """A streamed source turned out not to be in time order (or, rarely, to mix chunks with and without its timeline
    after repeats were handled): what was passed on cannot be taken back, so the caller runs again with the source
    read whole (`with_sorting_retry`). Not a user error: it never reaches the user."""

    def __init__(self, source: str, path: Path | str) -> None:
        super().__init__(f"source '{source}': rows of {path} are out of time order; read it whole to sort it")
        self.source = source
        self.path = path


@contextmanager
def sorted_in_memory(*sources: str) -> Iterator[None]:
    """Streams opened within the block read these sources (every source when none is named) whole and sort them, as
    before streaming: for a reader that must judge a source whole, such as `check`'s sample of the first rows."""
    token = _READ_WHOLE.set(_READ_WHOLE.get() | (frozenset(sources) or {EVERY_SOURCE}))
    try:
        yield
    finally:
        _READ_WHOLE.reset(token)


def with_sorting_retry(run: Callable[[], T]) -> T:
    """`run()`, run again, from the start, with each source that raised `NeedsSorting` read whole. `run` must open
    its streams itself: a stream keeps the mode it was opened with."""
    whole: frozenset[str] = frozenset()
    while True:  # one iteration per source found out of order, and one more
        token = _READ_WHOLE.set(_READ_WHOLE.get() | whole)
        try:
            return run()
        except Exception as exc:
            found = needs_sorting(exc)
            if found is None or found.source in whole:  # a source read whole never raises it
                raise
            whole |= {found.source}
        finally:
            _READ_WHOLE.reset(token)


def needs_sorting(exc: BaseException) -> NeedsSorting | None:
    """The `NeedsSorting` that `exc` is or wraps (Rerun may wrap an exception raised in a Python-fed stream)."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:  # one iteration per link of the chain
        if isinstance(current, NeedsSorting):
            return current
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return None


def _index_values(batch: pa.RecordBatch, timeline: str) -> np.ndarray | None:
    position = batch.schema.get_field_index(timeline)
    if position < 0:
        return None
    column = batch.column(position)
    if not (pa.types.is_integer(column.type) or pa.types.is_timestamp(column.type) or pa.types.is_duration(column.type)):
        return None
    return np.asarray(column.cast(pa.int64()).to_numpy(zero_copy_only=False))


def _fresh(batches: list[pa.RecordBatch]) -> tuple[pa.Table, dict[bytes, bytes]]:
    """The batches as one table without row ids or chunk id, and the chunk metadata to rebuild chunks with: chunks
    made from it get fresh ids, so their row order is the order given."""
    metadata = {k: v for k, v in (batches[0].schema.metadata or {}).items() if k != b"rerun:id"}
    stripped = [b.drop_columns([ROW_ID]) if ROW_ID in b.schema.names else b for b in batches]
    return pa.Table.from_batches([b.replace_schema_metadata(metadata) for b in stripped]), metadata


def _chunks(table: pa.Table, metadata: dict[bytes, bytes]) -> Iterator[Chunk]:
    from rerun.chunk import Chunk

    for batch in table.to_batches():
        yield from Chunk.from_record_batch(batch.replace_schema_metadata(metadata))


def _rebuilt(batches: list[pa.RecordBatch], rows: np.ndarray) -> Iterator[Chunk]:
    """The rows in the given order, as new chunks of BLOCK_ROWS rows (fresh row ids, so the row order is the time order)."""
    table, metadata = _fresh(batches)
    for start in range(0, len(rows), BLOCK_ROWS):  # one iteration per block of rows
        yield from _chunks(table.take(pa.array(rows[start : start + BLOCK_ROWS])).combine_chunks(), metadata)


def _first_timeline(batch: pa.RecordBatch) -> str:
    """A recording's rows may sit on several timelines; the first index column of the first chunk is checked."""
    kinds = [(field.name, (field.metadata or {}).get(b"rerun:kind")) for field in batch.schema]
    return next((name for name, kind in kinds if kind == b"index"), "")


def _repeat_error(
    label: str, path: Path | str, timeline: str, count: int, value: int, rows: Iterable[int], total: int, where: Where | None
) -> UserError:
    """`count` rows repeat an earlier row's value; the first repeated `value` is on `total` rows, `rows` the first of them."""
    shown = ", ".join(str(int(r)) for r in list(rows)[:4]) + (f" and {total - 4} more" if total > 4 else "")
    return UserError(
        f"{label}: {path} has {count} rows whose {timeline} repeats an earlier row's; the first: "
        f"{timeline} = {value} at rows {shown} (counting from 0): two poses at one time. "
        f"Remove the duplicates, or set duplicates: keep_last on the source to keep the last row of each",
        where,
    )


def _kept_note(label: str, count: int, path: Path | str, timeline: str) -> None:
    _note(f"{label}: {count} rows of {_name(path)} repeat a {timeline} value; kept the last of each (duplicates: keep_last)")


def _check(chunks: list[Chunk], timeline: str | None, policy: str, label: str, path: Path | str, where: Where | None) -> Iterator[Chunk]:
    """The whole source at once (rows out of order): sorted, stably, with the repeats' policy applied."""
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
        if policy != "keep_last":
            raise _repeat_error(label, path, timeline, int(repeated.sum()), int(ordered[first]), rows[:4], len(rows), where)
        keep = np.append(~repeated, True)  # the last of each run of equal values is the file's last row with it
        order = order[keep]
        _kept_note(label, int(repeated.sum()), path, timeline)
    if bool(np.any(np.diff(values) < 0)):
        moved = int(np.count_nonzero(order != np.arange(len(order)))) if len(order) == len(values) else len(order)
        _note(f"{label}: rows of {_name(path)} are out of {timeline} order ({moved} rows moved); sorted by {timeline}, stably")
    yield from _rebuilt(batches, order)


@dataclass
class _FirstRepeat:
    """Under `error`: the first repeated value and its run of rows, which may go on into later chunks."""

    value: int
    start: int  # its first row, counting from 0
    rows: int


def _streamed(chunks: Iterator[Chunk], timeline: str | None, policy: str, label: str, path: Path | str, plan: Any) -> Iterator[Chunk]:
    """The rows as they come, checked chunk by chunk against the previous row (only index values are kept)."""
    check = _StreamCheck(policy == "keep_last", plan.name, path)
    for chunk in chunks:  # one iteration per chunk
        batch = chunk.to_record_batch()
        if timeline is None:
            timeline = _first_timeline(batch)
        values = _index_values(batch, timeline)
        if values is None:  # no such timeline (a generated one): nothing is checked, every chunk passed on as it is
            yield from check.unchecked(chunk)
            yield from chunks
            return
        yield from check.passed_on(chunk, batch, values)
    yield from check.end(label, timeline or "", plan.where)


@dataclass
class _StreamCheck:
    """What the streamed check keeps between chunks: the previous row's index value, the rows and repeats so far, and
    what the policy holds back (`keep_last`: one chunk, whose last row may repeat in the next; `error`: the first repeat,
    after which nothing more is passed on)."""

    keep_last: bool
    source: str
    path: Path | str
    last: int | None = None  # the index value of the previous row
    seen: int = 0  # rows before this chunk
    repeats: int = 0
    first: _FirstRepeat | None = None  # under `error`: once set, nothing more is passed on
    held: tuple[Chunk, pa.RecordBatch, np.ndarray] | None = None  # under `keep_last`: a chunk and which rows stay

    def unchecked(self, chunk: Chunk) -> Iterator[Chunk]:
        """The chunks passed on as they are once a chunk lacks the timeline; repeats already seen cannot be undone."""
        if self.repeats:
            raise NeedsSorting(self.source, self.path)
        if self.held is not None:
            yield self.held[0]
        yield chunk

    def passed_on(self, chunk: Chunk, batch: pa.RecordBatch, values: np.ndarray) -> Iterator[Chunk]:
        """What of `chunk` goes on now; rows out of order raise `NeedsSorting` (earlier rows are gone: read it whole)."""
        if len(values) == 0:
            if self.first is None:
                yield chunk
            return
        steps = np.diff(values, prepend=values[0] if self.last is None else self.last)
        if bool(np.any(steps < 0)):
            raise NeedsSorting(self.source, self.path)
        equal = steps == 0
        equal[0] = equal[0] and self.last is not None
        self.repeats += int(np.count_nonzero(equal))
        if self.keep_last:
            yield from self._keeping_last(chunk, batch, equal)
        else:
            yield from self._until_a_repeat(chunk, values, equal)
        self.last = int(values[-1])
        self.seen += len(values)

    def _keeping_last(self, chunk: Chunk, batch: pa.RecordBatch, equal: np.ndarray) -> Iterator[Chunk]:
        """The held chunk goes on (without its last row when this chunk goes on with its value); this one is held."""
        if self.held is not None:
            self.held[2][-1] = not equal[0]
            yield from _kept(*self.held)
        self.held = (chunk, batch, np.append(~equal[1:], True))

    def _until_a_repeat(self, chunk: Chunk, values: np.ndarray, equal: np.ndarray) -> Iterator[Chunk]:
        """The chunk goes on until the first repeat; from then on only the rows of that repeated value are counted."""
        if self.first is not None:
            self.first.rows += int(np.count_nonzero(values == self.first.value))
        elif equal.any():
            at = int(np.argmax(equal))
            value = int(values[at])
            self.first = _FirstRepeat(value, self.seen + at - 1, int(np.count_nonzero(values == value)) + (at == 0))
        else:
            yield chunk

    def end(self, label: str, timeline: str, where: Where | None) -> Iterator[Chunk]:
        """The held chunk; then the first repeat's error under `error`, or one note of the rows `keep_last` dropped."""
        if self.held is not None:
            yield from _kept(*self.held)
        if self.first is not None:
            rows = range(self.first.start, self.first.start + min(self.first.rows, 4))
            raise _repeat_error(label, self.path, timeline, self.repeats, self.first.value, rows, self.first.rows, where)
        if self.repeats:
            _kept_note(label, self.repeats, self.path, timeline)


def _kept(chunk: Chunk, batch: pa.RecordBatch, keep: np.ndarray) -> Iterator[Chunk]:
    """The chunk as it is when it keeps every row, else its kept rows as a new chunk (fresh row ids)."""
    if bool(keep.all()):
        yield chunk
    else:
        yield from _rebuilt([batch], np.flatnonzero(keep))


def _note(text: str) -> None:
    note(text)


def _reading(stream: LazyChunkStream, path: Path | str, where: Where | None) -> Iterator[Chunk]:
    """The chunks of `stream`; a reader's decoding error (a corrupt chunk) becomes a user error naming the file."""
    chunks = iter(stream)
    while True:  # one iteration per chunk
        try:
            chunk = next(chunks)
        except StopIteration:
            return
        except (RuntimeError, ValueError, OSError) as exc:
            for cause in (exc.__cause__, exc.__context__):
                if isinstance(cause, UserError):  # raised by one of our own callbacks: keep it
                    raise cause from None
            reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise UserError(f"cannot read {path}, it is probably corrupt: {reason}", where) from None
        yield chunk


def _name(path: Path | str) -> str:
    """A file's own name, for a note: a local path's, or a remote file's URL's last segment."""
    return path.name if isinstance(path, Path) else path.rsplit("/", 1)[-1]


def read_all(stream: LazyChunkStream, path: Path | str, where: Where | None) -> list[Chunk]:
    """Every chunk of `stream`; a reader's decoding error (a corrupt chunk) becomes a user error naming the file."""
    return list(_reading(stream, path, where))


def in_time_order(stream: LazyChunkStream, timeline: str | None, plan: Any, path: Path | str, in_memory: bool = False) -> LazyChunkStream:
    """`stream` (temporal chunks of the values' entity) checked for repeated index values and sorted on `timeline`
    (None: the recording's first timeline). Streamed, unless `in_memory` or the source is read whole
    (`sorted_in_memory`, decided here, when the stream is opened): then read whole first and sorted."""
    from rerun.chunk import LazyChunkStream

    label = f"source '{plan.name}'"
    policy = str(getattr(plan, "duplicates", "error"))  # the source's `duplicates:`, `error` unless the plan has another
    whole = in_memory or bool({EVERY_SOURCE, plan.name} & _READ_WHOLE.get())

    def checked() -> Iterator[Chunk]:
        if whole:
            yield from _check(read_all(stream, path, plan.where), timeline, policy, label, path, plan.where)
        else:
            yield from _in_blocks(_streamed(_reading(stream, path, plan.where), timeline, policy, label, path, plan))

    return LazyChunkStream.from_iter(checked())


def _in_blocks(chunks: Iterable[Chunk]) -> Iterator[Chunk]:
    """Consecutive small chunks of one entity joined into blocks of about `BLOCK_ROWS` rows, in order (fresh row
    ids); a chunk of one or two blocks' size goes on untouched, a larger one is cut into blocks. Each block becomes one FK chunk of the recording, so a
    source of small chunks (an .rrd logged row by row, a reader's 1024-row chunks) gives chunks as large as a
    collected store's, and the FK runs on batches of its best size."""
    pending: list[pa.RecordBatch] = []
    rows = 0
    key: tuple[str, tuple[str, ...]] | None = None
    for chunk in chunks:  # one iteration per chunk
        if not pending and BLOCK_ROWS <= chunk.num_rows <= 2 * BLOCK_ROWS:
            yield chunk
            continue
        if not pending and chunk.num_rows > 2 * BLOCK_ROWS:  # a reader's large chunk (HDF5: ~2 MB): split, so the
            yield from _rebuilt([chunk.to_record_batch()], np.arange(chunk.num_rows))  # FK's batches stay bounded
            continue
        batch = chunk.to_record_batch()
        chunk_key = (chunk.entity_path, tuple(batch.schema.names))
        if pending and chunk_key != key:
            yield from _joined(pending)
            pending, rows = [], 0
        pending.append(batch)
        rows += batch.num_rows
        key = chunk_key
        if rows >= BLOCK_ROWS:
            yield from _joined(pending)
            pending, rows = [], 0
    if pending:
        yield from _joined(pending)


def _joined(batches: list[pa.RecordBatch]) -> Iterator[Chunk]:
    """The batches' rows, in order, as one chunk (fresh row ids)."""
    table, metadata = _fresh(batches)
    yield from _chunks(table.combine_chunks(), metadata)


def with_duplicates(plan: Any, spec: dict[str, Any]) -> Any:
    """The plan with the source's `duplicates:` policy."""
    from dataclasses import replace

    return replace(plan, duplicates=spec.get("duplicates", "error"))


def in_blocks(stream: LazyChunkStream) -> LazyChunkStream:
    """A source with no time order to check (rows numbered by its reader) in blocks of about `BLOCK_ROWS` rows."""
    from rerun.chunk import LazyChunkStream

    return LazyChunkStream.from_iter(_in_blocks(stream))

"""Index values a Rerun timeline can hold: int64 nanoseconds (a time) or int64 steps (a sequence), never i64::MIN
(Rerun's static time). A value beyond (a uint64 at or above 2^63, seconds whose nanoseconds overflow) would be written
as a wrapped, meaningless timeline: it is refused naming the column, the row and the value, on whole columns with numpy.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from ..errors import UserError, Where
from ..plan import IndexPlan

INT64_MAX = 2**63 - 1  # the largest time Rerun keeps; the smallest is -INT64_MAX (i64::MIN means static)
NANOSECONDS = {"s": 1_000_000_000, "ms": 1_000_000, "us": 1_000, "ns": 1}
_WORDS = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}


def factor_of(index: IndexPlan) -> int:
    """Nanoseconds per index unit (1 for a sequence: its values are the timeline's)."""
    return 1 if index.kind == "sequence" else NANOSECONDS[index.unit or "s"]


def first_outside(values: np.ndarray, factor: int) -> int | None:
    """The position of the first value whose timeline value (value x factor) does not fit, or None when all fit."""
    limit = INT64_MAX // factor
    if values.dtype.kind == "u":
        bad = values > np.uint64(limit)
    elif values.dtype.kind == "i":
        bad = (values > limit) | (values < -limit)
    elif values.dtype.kind == "f":
        with np.errstate(all="ignore"):
            scaled = values.astype(np.float64) * factor
            bad = ~(np.abs(scaled) < float(2**63))  # NaN and inf too; 2^63 is the first float beyond int64
    else:
        return None
    return int(np.argmax(bad)) if bool(bad.any()) else None


def _numbers(array: pa.Array) -> tuple[np.ndarray, int | None]:
    """The array as numpy and the factor its own type implies (a timestamp or duration knows its unit), or None."""
    if pa.types.is_timestamp(array.type) or pa.types.is_duration(array.type):
        return np.asarray(array.cast(pa.int64()).to_numpy(zero_copy_only=False)), NANOSECONDS[array.type.unit]
    return np.asarray(array.to_numpy(zero_copy_only=False)), None


def index_problem(array: pa.Array | np.ndarray, index: IndexPlan, first_row: int, label: str) -> str | None:
    """Why this batch of index values (rows first_row.. of the source) cannot be a timeline, or None. `label` names the
    column ("index column 'timestamp' of FILE")."""
    if isinstance(array, pa.ChunkedArray):
        array = array.combine_chunks()
    if isinstance(array, pa.Array):
        if array.null_count:
            row = first_row + int(np.argmax(array.is_null().to_numpy(zero_copy_only=False)))
            return f"{label} is empty at row {row} (counting from 0): every row needs its time"
        values, own = _numbers(array)
    else:
        values, own = array, None
    factor = own if own is not None else factor_of(index)
    at = first_outside(values, factor)
    if at is None:
        return None
    value = values[at]
    unit = "" if index.kind == "sequence" else f" {next(u for u, f in NANOSECONDS.items() if f == factor)}"
    return f"{label} holds {value}{unit} at row {first_row + at} (counting from 0), {_beyond(value, index, factor, own is None)}"


def _beyond(value: Any, index: IndexPlan, factor: int, unit_from_config: bool) -> str:
    if isinstance(value, float | np.floating) and not np.isfinite(value):
        return "not a time: every row needs a finite time"
    if index.kind == "sequence":
        return f"beyond a sequence timeline's range (±{INT64_MAX}); number the rows within it"
    finer = [unit for unit, f in NANOSECONDS.items() if unit_from_config and f < factor and first_outside(np.asarray([value]), f) is None]
    hint = f"; if the column counts {_WORDS[finer[0]]}, say unit: {finer[0]}" if finer else ""
    return f"beyond a timeline's range (±{INT64_MAX} ns, about ±292 years around 1970){hint}"


def check_index_batches(batches: Iterable[pa.Array | np.ndarray], index: IndexPlan, label: str, where: Where | None) -> None:
    """Every batch of a source's index column, in order: the first value that cannot be a timeline is a user error."""
    row = 0
    for batch in batches:  # one iteration per batch of rows
        problem = index_problem(batch, index, row, label)
        if problem is not None:
            raise UserError(problem, where)
        row += len(batch)


def check_parquet_index(path: Path, index: IndexPlan, where: Where | None, batch_rows: int = 1 << 20) -> None:
    """A parquet file's index column, read alone, batch by batch (8 MB of int64 each)."""
    import pyarrow.parquet as pq

    try:
        file = pq.ParquetFile(path)
        batches = (batch.column(0) for batch in file.iter_batches(batch_size=batch_rows, columns=[index.column]))
        check_index_batches(batches, index, f"index column '{index.column}' of {path}", where)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise UserError(f"cannot read the index column '{index.column}' of {path}: {exc}", where) from None

"""The segment's summary for the manifest (manifest_entry.py), gathered during the run's one pass over the data.

Time ranges: the first and the last chunk of each source (`observed`), not every chunk. The preview: the FK's values
folded into at most `FINE_BUCKETS` (min, max) buckets, merged in pairs as the rows outgrow them, so memory does not
grow with the recording and the row count need not be known ahead; at the end reduced to `BUCKETS` and quantised.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..errors import shown
from .manifest_entry import BUCKETS, EMPTY, NOTE_LIMIT, NOTES, PREVIEW_JOINTS, JointPreview, SegmentSummary, TimelineKind, TimeRange

if TYPE_CHECKING:
    import pyarrow as pa
    from rerun.chunk import Chunk

    from ..plan import JointChannel
    from ..sources import SourceStream
    from .differences import PairDifferences

FINE_BUCKETS = 1024  # buckets kept while the values stream by (per robot: 1024 x joints x 2 float64)
UNLIMITED_SPAN = 2 * math.pi  # what a joint without limits moves against, for choosing the preview's joints


class TimeRanges:
    """The first and last index value of every timeline the joint values sit on, over every source read: the earliest
    first and the latest last of the sources (rows are in time order: the sources' ordering check sorts them)."""

    def __init__(self) -> None:
        self.sources: list[SourceTimes] = []

    def source(self) -> SourceTimes:
        """A new source's record: its chunks come in its own order, which other sources' chunks interleave."""
        self.sources.append(SourceTimes())
        return self.sources[-1]

    def result(self) -> tuple[TimeRange, ...]:
        ranges: dict[str, tuple[TimelineKind, int, int]] = {}
        for source in self.sources:
            for name, (kind, first, last) in source.ends().items():
                known = ranges.get(name)
                ranges[name] = (kind, first, last) if known is None else (kind, min(first, known[1]), max(last, known[2]))
        return tuple(TimeRange(name, kind, first, last) for name, (kind, first, last) in sorted(ranges.items()))


class SourceTimes:
    """One source's first index value per timeline, read from the first chunk holding it, and the last chunk holding it,
    whose last value is read at the end: two chunks read per source, not every chunk."""

    def __init__(self) -> None:
        self.first: dict[str, tuple[TimelineKind, int]] = {}
        self.last_chunk: dict[str, Chunk] = {}  # one chunk kept per timeline: bounded memory

    def observe(self, chunk: Chunk) -> None:
        names = chunk.timeline_names
        if chunk.is_static or not names or chunk.num_rows == 0:
            return
        if any(name not in self.first for name in names):
            batch = chunk.to_record_batch()
            for name in names:
                value = self.first.get(name) or _end(batch, name, 0)
                if value is not None:
                    self.first[name] = value
        for name in names:
            self.last_chunk[name] = chunk

    def ends(self) -> dict[str, tuple[TimelineKind, int, int]]:
        """timeline -> (kind, first value, last value)."""
        batches = {id(chunk): chunk.to_record_batch() for chunk in self.last_chunk.values()}
        ends = {}
        for name, (kind, first) in self.first.items():
            last = _end(batches[id(self.last_chunk[name])], name, -1)
            if last is not None and last[1] >= first:
                ends[name] = (kind, first, last[1])
        return ends


def _end(batch: pa.RecordBatch, name: str, row: int) -> tuple[TimelineKind, int] | None:
    """The timeline's kind and its value at `row` of the batch (int64: nanoseconds or steps); None for another type
    or a null, or when no column has its name."""
    position = batch.schema.get_field_index(name)
    if position < 0:
        return None
    column = batch.column(position)
    kind = _kind(column.type)
    value = column.slice(row % len(column), 1).cast("int64")[0].as_py() if kind is not None else None
    return None if kind is None or value is None else (kind, value)


def _kind(arrow_type: pa.DataType) -> TimelineKind | None:
    import pyarrow as pa

    if pa.types.is_timestamp(arrow_type):
        return "timestamp"
    if pa.types.is_duration(arrow_type):
        return "duration"
    return "sequence" if pa.types.is_integer(arrow_type) else None


class ValuePreview:
    """One robot's driven joint values folded into at most `FINE_BUCKETS` (min, max) buckets of `width` rows each, batch
    by batch in row order (see the module); `result` reduces them to the stored preview."""

    def __init__(self, robot: str, channels: tuple[JointChannel, ...], pairs: tuple[PairDifferences, ...] = ()) -> None:
        self.robot = robot
        self.channels = channels
        self.pairs = pairs  # the compared pairs this robot is a side of (compare:): they see the same values
        count = len(channels)
        self.width = 1
        self.rows = 0
        self.minima = np.full((FINE_BUCKETS, count), np.inf)  # an empty bucket: min +inf, max -inf
        self.maxima = np.full((FINE_BUCKETS, count), -np.inf)
        self._lock = threading.Lock()

    def add(self, values: np.ndarray, left_out: np.ndarray | None) -> None:
        """A batch of (rows x joints) URDF values, the driven joints first; `left_out` rows count but show nothing."""
        driven = values[:, : len(self.channels)]
        rows = len(driven)
        if not rows:
            return
        for pair in self.pairs:
            pair.add(self.robot, driven, left_out)
        # Rows left out count as +inf for the minima and -inf for the maxima: np.minimum and np.maximum (4x faster
        # than fmin and fmax) then need no NaN, which only a run that fails after its pass holds (NaN: its bucket empty).
        lows = driven if left_out is None else np.where(left_out[:, None], np.inf, driven)
        highs = driven if left_out is None else np.where(left_out[:, None], -np.inf, driven)
        with self._lock:
            while self.rows + rows > FINE_BUCKETS * self.width:
                self._merge_pairs()
            first, width = self.rows, self.width
            buckets = np.arange(first // width, (first + rows - 1) // width + 1)
            starts = np.maximum(buckets * width - first, 0)
            self.minima[buckets] = np.minimum(self.minima[buckets], np.minimum.reduceat(lows, starts, axis=0))
            self.maxima[buckets] = np.maximum(self.maxima[buckets], np.maximum.reduceat(highs, starts, axis=0))
            self.rows += rows

    def _merge_pairs(self) -> None:
        """Neighbouring buckets merged: half as many, twice as wide."""
        half = FINE_BUCKETS // 2
        self.minima[:half] = np.minimum(self.minima[0::2], self.minima[1::2])
        self.maxima[:half] = np.maximum(self.maxima[0::2], self.maxima[1::2])
        self.minima[half:] = np.inf
        self.maxima[half:] = -np.inf
        self.width *= 2

    def result(self) -> JointPreview | None:
        """The preview of the joints that move most (all when there are few), None without rows or driven joints."""
        if not self.rows or not len(self.channels):
            return None
        used = -(-self.rows // self.width)
        buckets = min(BUCKETS, self.rows)
        # fine bucket k (rows k*width..) goes to the stored bucket its first row falls in
        owner = (np.arange(used) * self.width * buckets) // self.rows
        starts = np.searchsorted(owner, np.arange(buckets))
        minima = np.minimum.reduceat(self.minima[:used], starts, axis=0)
        maxima = np.maximum.reduceat(self.maxima[:used], starts, axis=0)
        seen_low, seen_high = minima.min(axis=0), maxima.max(axis=0)  # +inf and -inf for a joint without a value
        chosen = self._chosen(seen_low, seen_high)
        low, high, limited = self._scales(chosen, seen_low, seen_high)
        codes = quantised(minima[:, chosen], maxima[:, chosen], low, high).reshape(-1)
        return JointPreview(
            self.robot,
            self.rows,
            buckets,
            tuple(self.channels[i].joint for i in chosen),
            tuple(float(v) for v in low),
            tuple(float(v) for v in high),
            tuple(bool(v) for v in limited),
            codes.tobytes(),
        )

    def _chosen(self, seen_low: np.ndarray, seen_high: np.ndarray) -> np.ndarray:
        """Positions of the joints to show, in the robot's order: those with the largest range seen relative to their
        limits' span (2 pi for a joint without limits), at most `PREVIEW_JOINTS`; ties keep the robot's order."""
        if len(self.channels) <= PREVIEW_JOINTS:
            return np.arange(len(self.channels))
        spans = np.array([_span(c) for c in self.channels])
        with np.errstate(all="ignore"):  # a joint without a value moved -inf (NaN: -1), so last
            moved = np.nan_to_num(np.minimum((seen_high - seen_low) / spans, 1.0), nan=-1.0, neginf=-2.0)
        return np.sort(np.argsort(-moved, kind="stable")[:PREVIEW_JOINTS])

    def _scales(self, chosen: np.ndarray, seen_low: np.ndarray, seen_high: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per chosen joint, the values of codes 0 and 255: its limits, else the range seen (else 0..1)."""
        channels = [self.channels[i] for i in chosen]
        limited = np.array([c.lower is not None and c.upper is not None and c.upper > c.lower for c in channels], dtype=bool)
        lower = np.array([c.lower if c.lower is not None else np.nan for c in channels], dtype=np.float64)
        upper = np.array([c.upper if c.upper is not None else np.nan for c in channels], dtype=np.float64)
        low = np.where(limited, lower, np.nan_to_num(seen_low[chosen], nan=0.0, posinf=0.0, neginf=0.0))
        high = np.where(limited, upper, np.nan_to_num(seen_high[chosen], nan=1.0, posinf=1.0, neginf=1.0))
        flat = ~(high > low)  # a joint without limits that never moved: its value mid-scale
        pad = np.maximum(1.0, np.abs(low))
        low = np.where(flat, low - pad / 2, low)
        high = np.where(flat, low + pad, high)
        return low, high, limited


def _span(channel: JointChannel) -> float:
    if channel.lower is not None and channel.upper is not None and channel.upper > channel.lower:
        return channel.upper - channel.lower
    return UNLIMITED_SPAN


def quantised(minima: np.ndarray, maxima: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(buckets x joints) minima and maxima as uint8 codes against each joint's [low, high], (joints x 2 x buckets):
    the min rounded down and the max up, so the band holds every value; values beyond the scale are clipped to it;
    a bucket without values (min +inf, max -inf) or with a NaN is (255, 0). Values near the float range (a joint
    passed through far beyond its limits, `on_violation: ignore`) give codes at the ends, never a warning."""
    with np.errstate(all="ignore"):
        scale = 255.0 / (high - low)
        lows = np.clip(np.nan_to_num(np.floor((minima - low) * scale), nan=0.0), 0, 255)
        highs = np.clip(np.nan_to_num(np.ceil((maxima - low) * scale), nan=255.0), 0, 255)
        empty = ~(minima <= maxima)
    lows = np.where(empty, EMPTY[0], lows).astype(np.uint8)
    highs = np.where(empty, EMPTY[1], highs).astype(np.uint8)
    return np.stack([lows.T, highs.T], axis=1)


def segment_summary(
    robots: tuple[str, ...],
    times: TimeRanges,
    previews: list[ValuePreview],
    notes: tuple[str, ...],
    pairs: tuple[PairDifferences, ...] = (),
) -> SegmentSummary:
    """The summary of one written segment, from what its pass gathered and the notes the run made of it."""
    made = (preview.result() for preview in previews)
    return SegmentSummary(
        robots=robots,
        timelines=times.result(),
        notes=tuple(shown(note, NOTE_LIMIT) for note in notes[:NOTES]),
        notes_left_out=max(len(notes) - NOTES, 0),
        previews=tuple(p for p in made if p is not None),
        differences=tuple(pair.result() for pair in pairs),
    )


def observed(source: SourceStream, times: TimeRanges) -> SourceStream:
    """`source` with its chunks' index values noted in `times` as they pass (the values' entity only)."""
    from rerun.chunk import LazyChunkStream

    record = times.source()

    def chunks() -> Iterator[Chunk]:
        for chunk in source.stream:  # one iteration per chunk
            if chunk.entity_path == source.entity:
                record.observe(chunk)
            yield chunk

    return replace(source, stream=LazyChunkStream.from_iter(chunks()))

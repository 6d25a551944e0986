"""A long segment's progress while it is written: rows through the forward kinematics, out of the rows the source's
metadata announces (none for CSV and .rrd: then no share and no time left), the rate and the time left.

On a terminal the line is redrawn in place; otherwise a plain line goes to the `urdf_pipeline` logger every
`METER_SECONDS`, so a CI log shows a long run moving. Only a run's one segment has a meter: parallel workers' redrawn
lines would garble each other (the run's own progress speaks for many).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, TextIO

from ..plan import Hdf5SourcePlan, LeRobotSourcePlan, McapSourcePlan, ParquetSourcePlan, RecordingPlan, SourcePlan
from ..sources import module_for

LOGGER = logging.getLogger("urdf_pipeline")
METER_SECONDS = 5.0  # a plain line this often when stderr is not a terminal (tests set it to 0)
REDRAW_SECONDS = 0.2  # a terminal's line is redrawn at most this often


def _clock(seconds: float) -> str:
    """`0:07`, `12:34`, `1:02:03`: time left as a person reads it."""
    whole = int(round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def meter_line(label: str, rows: int, total: int | None, elapsed: float) -> str:
    """`episode_000: 1,200,000 of 3,000,000 rows (40%), 400,000 rows/s, 0:04 left`; without a known total, rows and
    rate only. The total is what the metadata said: rows beyond it are counted, the share stops at 100%."""
    rate = rows / elapsed if elapsed > 0 else 0.0
    speed = f"{rate:,.0f} rows/s"
    if not total:
        return f"{label}: {rows:,} rows, {speed}"
    share = min(rows, total) / total
    left = "finishing" if rows >= total else f"{_clock((total - rows) / rate)} left" if rate > 0 else "? left"
    return f"{label}: {rows:,} of {total:,} rows ({share:.0%}), {speed}, {left}"


class RowMeter:
    """Rows of one source through the FK (`add` is called from Rerun's reader threads, hence the lock)."""

    def __init__(self, label: str, total: int | None, stream: TextIO | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.label = label
        self.total = total
        self.stream = stream or sys.stderr
        self.redraw = _is_terminal(self.stream)
        self.rows = 0
        self._clock = clock
        self._started = self._last = clock()
        self._drawn = False
        self._lock = threading.Lock()

    def add(self, rows: int) -> None:
        with self._lock:
            self.rows += rows
            now = self._clock()
            if now - self._last < (REDRAW_SECONDS if self.redraw else METER_SECONDS) or not LOGGER.isEnabledFor(logging.INFO):
                return
            self._last = now
            line = meter_line(self.label, self.rows, self.total, now - self._started)
            if self.redraw:
                if not self._drawn:
                    LOGGER.addFilter(self._clear_before_record)
                self.stream.write(f"\rurdf-pipeline: {line}\x1b[K")
                self.stream.flush()
                self._drawn = True
            else:
                LOGGER.info("urdf-pipeline: %s", line)

    def _clear_before_record(self, record: logging.LogRecord) -> bool:
        """A line logged while the meter's line is drawn (a note, a relayed Rerun line) starts on a clean line; the
        next redraw puts the meter back below it."""
        with self._lock:
            self._clear()
        return True

    def _clear(self) -> None:
        if self._drawn:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._drawn = False

    def finish(self) -> None:
        """Clear a redrawn line: what follows (the segment's result) starts on a clean line."""
        LOGGER.removeFilter(self._clear_before_record)
        with self._lock:
            self._clear()


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # a closed or stand-in stream
        return False


def known_rows(source: SourcePlan, rows_expected: int | None) -> int | None:
    """The rows a source's metadata announces (read from footers and summaries only), None when it says none."""
    try:
        if isinstance(source, Hdf5SourcePlan):
            return source.rows
        if isinstance(source, ParquetSourcePlan):
            import pyarrow.parquet as pq

            return int(pq.ParquetFile(source.path).metadata.num_rows)
        if isinstance(source, LeRobotSourcePlan):
            if rows_expected is not None:
                return rows_expected
            kind: Any = module_for(source)  # the lerobot module: its episode lengths are not part of SourceKind
            return kind.episodes(source).get(source.episode)
        if isinstance(source, McapSourcePlan):
            from rerun.chunk import McapReader

            channels = McapReader(source.path).info().channels
            counts = [c.message_count for c in channels if _topic(c.topic) == _topic(source.topic)]
            known = [count for count in counts if count is not None]
            return sum(known) if counts and len(known) == len(counts) else None
    except Exception:  # a meter's total is a nicety: a file that changed since the checks is the read's to report
        return None
    return None


def _topic(topic: str) -> str:
    return topic if topic.startswith("/") else f"/{topic}"


def source_meter(plan: RecordingPlan, source: SourcePlan, rows_expected: int | None) -> RowMeter:
    """The meter of one source of a segment, named after the segment (and the source, when several drive robots);
    the pass that reads the source finishes it (segment.py)."""
    driving = [s for s in plan.sources if plan.robots_for(s.name)]
    label = plan.output.recording_id if len(driving) <= 1 else f"{plan.output.recording_id} ({source.name})"
    return RowMeter(label, known_rows(source, rows_expected))

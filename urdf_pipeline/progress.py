"""Progress on stderr for long runs, throttled so a million-row run prints a line every few seconds, not per batch."""

from __future__ import annotations

import sys
import threading
import time
from typing import Protocol, TextIO


def say(message: str) -> None:
    print(f"urdf-pipeline: {message}", file=sys.stderr, flush=True)


class RowProgress:
    """Rows through the FK of one robot: a line every few seconds, with the share done and an ETA when the row count
    is known from the source's metadata."""

    def __init__(self, label: str, every_seconds: float = 5.0, total: int | None = None) -> None:
        self.label = label
        self.every = every_seconds
        self.total = total
        self.rows = 0
        self._started = self._last = time.monotonic()
        self._lock = threading.Lock()

    def add(self, rows: int) -> None:
        with self._lock:
            self.rows += rows
            now = time.monotonic()
            if now - self._last >= self.every:
                self._last = now
                say(self.line(now - self._started))

    def line(self, elapsed: float) -> str:
        rate = self.rows / max(elapsed, 1e-9)
        if not self.total:
            return f"{self.label}: {self.rows:,} rows ({rate:,.0f} rows/s)"
        done = min(self.rows, self.total)
        eta = time.strftime("%H:%M:%S", time.gmtime((self.total - done) / max(rate, 1e-9)))
        return f"{self.label}: {done:,} of {self.total:,} rows ({100 * done / self.total:.0f}%, {rate:,.0f} rows/s, ETA {eta})"


class SegmentProgress:
    """Segments done, frames/s and ETA: one redrawn bar when stderr is a terminal, else one plain line per segment."""

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.width = width
        self.total = self.finished = self.frames = self.frames_expected = self.frames_of_expected = 0
        self.started = time.monotonic()
        self._last_draw = 0.0

    def start(self, total: int, frames_expected: int, skipped: int) -> None:
        self.total, self.finished, self.frames_expected = total, skipped, frames_expected
        self.started = time.monotonic()
        if skipped:
            self._line(f"{skipped} of {total} up to date (skipped)")

    def done(self, result: SegmentResultLike, frames_expected: int | None) -> None:
        self.finished += 1
        self.frames += result.frames
        self.frames_of_expected += frames_expected or 0
        if self.tty:
            self._draw(force=self.finished == self.total)
        else:
            reason = f": {result.reason.splitlines()[0]}" if result.status != "written" and result.reason else ""
            self._line(
                f"[{self.finished}/{self.total}] {result.label} {result.status} ({result.frames:,} frames, {result.seconds:.1f} s){reason}"
            )

    def finish(self) -> None:
        if self.tty and self._last_draw:
            self.stream.write("\n")
            self.stream.flush()

    def _eta(self, elapsed: float) -> str:
        if self.frames_expected and self.frames_of_expected:  # by frames: episodes differ in length
            remaining = elapsed * (self.frames_expected - self.frames_of_expected) / self.frames_of_expected
        elif self.finished:
            remaining = elapsed * (self.total - self.finished) / self.finished
        else:
            return "?"
        return time.strftime("%H:%M:%S", time.gmtime(max(remaining, 0)))

    def _draw(self, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last_draw < 0.2:
            return
        self._last_draw = now
        elapsed = max(now - self.started, 1e-9)
        filled = int(self.width * self.finished / max(self.total, 1))
        bar = "#" * filled + "-" * (self.width - filled)
        self.stream.write(
            f"\rurdf-pipeline [{bar}] {self.finished}/{self.total} segments, {self.frames / elapsed:,.0f} frames/s, ETA {self._eta(elapsed)}  "
        )
        self.stream.flush()

    def _line(self, message: str) -> None:
        print(f"urdf-pipeline: {message}", file=self.stream, flush=True)


class SegmentResultLike(Protocol):
    @property
    def label(self) -> str: ...
    @property
    def status(self) -> str: ...
    @property
    def frames(self) -> int: ...
    @property
    def seconds(self) -> float: ...
    @property
    def reason(self) -> str: ...

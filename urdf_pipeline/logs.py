"""What the tool tells a person while it works, through the `urdf_pipeline` logger (INFO for progress and notes,
WARNING for a config's warnings, DEBUG for what `--verbose` adds), and throttled progress for long runs.

A program that embeds the package silences or redirects it as any logger; the command line sends it to stderr
(`command_logging`). Errors are not logged: they are raised, and the command line's one exit point prints them.
"""

from __future__ import annotations

import logging
import os
import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Protocol, TextIO

from .errors import neutral_line, neutral_text

LOGGER = logging.getLogger("urdf_pipeline")


def say(message: str) -> None:
    LOGGER.info("urdf-pipeline: %s", message)


def note(text: str) -> None:
    """Something the run did that the user may want to know (rows sorted, duplicates kept, values clamped)."""
    LOGGER.info("note: %s", text)


def detail(message: str) -> None:
    """What `--verbose` adds: timings, per-segment notes of a many-segment run, the workers."""
    LOGGER.debug("urdf-pipeline: %s", message)


class _Stderr(logging.Handler):
    """Each record as one line on the sys.stderr of the moment (a test's capture, a redirected stream)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(self.format(record) + "\n")
            sys.stderr.flush()
        except RecursionError:
            raise
        except Exception:
            self.handleError(record)


class _Neutral(logging.Formatter):
    """`%(message)s`, each of its lines neutral (errors.neutral_text): names from input in a message (a joint named
    `::error::x`, a file name holding ESC or a newline) never forge a CI workflow command or reach the terminal raw."""

    def format(self, record: logging.LogRecord) -> str:
        return neutral_text(super().format(record))


def _handler() -> logging.Handler:
    handler = _Stderr()
    handler.setFormatter(_Neutral("%(message)s"))
    return handler


@contextmanager
def command_logging(level: int) -> Iterator[None]:
    """The command line's logging for one command: its lines on stderr at `level` (WARNING with --quiet, DEBUG with
    --verbose); the logger's state is given back after (tests and programs call `cli.main` in-process)."""
    handler = _handler()
    previous = LOGGER.level, LOGGER.propagate
    LOGGER.addHandler(handler)
    LOGGER.setLevel(level)
    LOGGER.propagate = False  # the lines are the command's, not the embedding program's root logger's
    try:
        yield
    finally:
        LOGGER.removeHandler(handler)
        LOGGER.setLevel(previous[0])
        LOGGER.propagate = previous[1]


def process_identity() -> str:
    return f"{os.uname().nodename}:{os.getpid()}"


def worker_logging(level: int, driver: str) -> None:
    """In a worker process (a pool's, a Ray task's), the level the run's own process had; its lines on stderr. Left
    alone in the run's own process (`driver`), whose logging is its caller's."""
    if process_identity() == driver:
        return
    if not any(isinstance(h, _Stderr) for h in LOGGER.handlers):
        LOGGER.addHandler(_handler())
        LOGGER.propagate = False
    LOGGER.setLevel(level)


class SegmentProgress:
    """Segments done, frames/s and ETA: one redrawn bar when stderr is a terminal, else one plain line per segment."""

    def __init__(self, stream: TextIO | None = None, width: int = 30) -> None:
        self.logged = stream is None  # its plain lines go through the logger; the bar is drawn on a terminal only
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
        if self.logged:
            say(message)
        else:
            print(neutral_line(f"urdf-pipeline: {message}"), file=self.stream, flush=True)


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


def _log_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int, file: TextIO | None = None, line: str | None = None
) -> None:
    LOGGER.debug("urdf-pipeline: %s", neutral_line(f"python warning: {filename}:{lineno}: {category.__name__}: {message}"))


@contextmanager
def warnings_logged() -> Iterator[None]:
    """Python's warnings (numpy's on NaN values, an overflowing cast) as DEBUG lines of the `urdf_pipeline` logger, not
    on stderr (`-q` means quiet; `-v` shows them): for a command (cli), and in a pool worker or a Ray task (execute)."""
    with warnings.catch_warnings():
        warnings.showwarning = _log_warning
        yield

"""Everything a command prints on stderr goes through the `urdf_pipeline` logger, at the level of `-q`/`-v`.

Rerun's Rust side (and other native code, and the pool's workers) writes to file descriptor 2 itself, past
`sys.stderr`: `stderr_through_logger` points fd 2 at a pipe whose lines a thread relays to the logger (`relayed` says
at which level), while `sys.stderr` keeps the original stream. The pipe and its thread are made once per process and
kept, so worker processes inherit it as their fd 2; at the end of a command a marker line is written through the pipe
and waited for (bounded), so everything written so far is relayed before fd 2 is given back.
"""

from __future__ import annotations

import io
import itertools
import logging
import os
import re
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

from ..errors import neutral_line
from ..process import ANSI_ESCAPE

LOGGER = logging.getLogger("urdf_pipeline")
# tracing's format (`TIME LEVEL target: message`) and env_logger's (`[TIME LEVEL target] message`)
_RERUN_LINE = re.compile(
    r"^\[?\d{4}-\d\d-\d\dT[0-9:.]+Z?\s+(?P<level>TRACE|DEBUG|INFO|WARN|WARNING|ERROR)\s+(?P<target>[\w.-]+(?:::[\w.-]+)*)\]?:?\s?(?P<message>.*)$"
)
# Rerun's ERROR lines say something went wrong that may not reach us as an exception (messages dropped): shown unless
# -q; everything else it logs (RUST_LOG=warn with -v, or what the user set) is detail.
RERUN_LEVELS = {"ERROR": logging.INFO, "WARN": logging.DEBUG, "WARNING": logging.DEBUG}
OTHER_LEVEL = logging.WARNING  # a line not in Rerun's format: a worker's own line (already filtered), a panic, ...
LONGEST_LINE = 65_536  # bytes held without a newline before they are relayed as a line anyway
FLUSH_SECONDS = 2.0  # at most this long, at the end of a command, for what was written so far to be relayed
_MARKER = b"\x00urdf-pipeline-relay-flush-"


OURS = ("urdf-pipeline:", "note:", "warning:", "error:")  # a worker's own lines: never a continuation of Rerun's
# How the further lines of a multi-line Rerun event start (a gRPC status's `- metadata: ...`, an error chain's
# `Caused by:` and its indented causes); another line read with it (a panic, a worker's line) is a line of its own
CONTINUATION = (" ", "\t", "- ", "Caused by")


def relayed(line: str, continuing: int | None = None) -> tuple[int, str, bool] | None:
    """The level and text a line written to fd 2 is logged with, and whether it is Rerun's; None for a blank line.
    `continuing`: the level of a Rerun line just before it in the same read (a multi-line event, such as an error
    and its `- metadata: ...` line), which a line that starts as such continuations do continues."""
    text = ANSI_ESCAPE.sub("", line).rstrip()
    if not text.strip():
        return None
    match = _RERUN_LINE.match(text)
    if match is not None:
        level = "WARN" if match["level"] == "WARNING" else match["level"]
        return RERUN_LEVELS.get(level, logging.DEBUG), neutral_line(f"rerun: {level} {match['target']}: {match['message']}"), True
    if continuing is not None and text.startswith(CONTINUATION) and not text.startswith(OURS):
        return continuing, neutral_line(f"rerun:   {text.strip()}"), True
    return OTHER_LEVEL, neutral_line(text), False


class _Relay:
    """One pipe and one thread per process: lines written to the pipe are logged as `relayed` says."""

    def __init__(self) -> None:
        self.read_end, self.write_end = os.pipe()
        self._flushes = itertools.count(1)
        self._seen = 0
        self._seen_changed = threading.Condition()
        threading.Thread(target=self._read, name="urdf-pipeline-stderr-relay", daemon=True).start()

    def _read(self) -> None:
        pending = b""
        while chunk := os.read(self.read_end, 65_536):
            pending += chunk
            *lines, pending = pending.split(b"\n")
            if len(pending) > LONGEST_LINE:
                lines, pending = [*lines, pending], b""
            continuing: int | None = None  # a multi-line event comes in one write, so in one read: never across reads
            for line in lines:
                continuing = self._line(line, continuing)

    def _line(self, raw: bytes, continuing: int | None) -> int | None:
        """Log one line; returns the level a next line continuing a Rerun event would have."""
        before, marker, number = raw.partition(_MARKER)
        if marker:
            with self._seen_changed:
                self._seen = max(self._seen, int(number or 0))
                self._seen_changed.notify_all()
        shown = relayed(before.decode("utf-8", "replace"), None if marker else continuing) if before else None
        if shown is None:
            return None if marker else continuing
        try:
            LOGGER.log(shown[0], "%s", shown[1])
        except Exception:  # the relay never dies of one line: what follows must still be read
            pass
        return shown[0] if shown[2] and not marker else None

    def flush(self, timeout: float) -> bool:
        """Wait until every line written to the pipe before now is logged (at most `timeout` seconds)."""
        number = next(self._flushes)
        try:
            os.write(self.write_end, _MARKER + str(number).encode() + b"\n")
        except OSError:
            return False
        with self._seen_changed:
            return self._seen_changed.wait_for(lambda: self._seen >= number, timeout)


_RELAY: list[_Relay] = []
_LOCK = threading.Lock()


def _shared_relay() -> _Relay:
    with _LOCK:
        if not _RELAY:
            _RELAY.append(_Relay())
        return _RELAY[0]


def _is_fd_2(stream: TextIO | None) -> bool:
    try:
        return stream is not None and stream.fileno() == 2
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):  # a test's capture, a closed stream
        return False


@contextmanager
def stderr_through_logger() -> Iterator[None]:
    """For one command: fd 2 relayed to the logger (see the module's docstring); `sys.stderr`, when it was fd 2, moved
    to a copy of the original fd 2. Both are given back after, once what was written has been relayed."""
    try:
        saved = os.dup(2)
    except OSError:  # no stderr at all: nothing to relay to
        yield
        return
    relay = _shared_relay()
    previous = sys.stderr
    moved = _is_fd_2(previous)
    if moved:
        previous.flush()
        sys.stderr = open(  # closed below, when the command is done
            saved, "w", encoding=previous.encoding, errors=previous.errors or "backslashreplace", buffering=1, closefd=False
        )
    os.dup2(relay.write_end, 2)
    try:
        yield
    finally:
        relay.flush(FLUSH_SECONDS)
        os.dup2(saved, 2)
        if moved:
            sys.stderr.flush()
            sys.stderr.close()
            sys.stderr = previous
        os.close(saved)

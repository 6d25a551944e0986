"""Progress on stderr for long runs, throttled so a million-row run prints a line every few seconds, not per batch."""

from __future__ import annotations

import sys
import threading
import time


def say(message: str) -> None:
    print(f"urdf-pipeline: {message}", file=sys.stderr, flush=True)


class RowProgress:
    def __init__(self, label: str, every_seconds: float = 5.0) -> None:
        self.label = label
        self.every = every_seconds
        self.rows = 0
        self._started = self._last = time.monotonic()
        self._lock = threading.Lock()

    def add(self, rows: int) -> None:
        with self._lock:
            self.rows += rows
            now = time.monotonic()
            if now - self._last >= self.every:
                self._last = now
                say(f"{self.label}: {self.rows:,} rows ({self.rows / (now - self._started):,.0f} rows/s)")

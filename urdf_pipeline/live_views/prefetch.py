"""A feed read on a thread of its own, so the stream is drained while the views are busy (compiling the plan at the
first message, sending a robot's meshes): a Foxglove server keeps about a thousand messages per client and drops the
oldest beyond, silently, so a client that stops reading for a second at 1 kHz would lose samples nobody is told of.

Here the samples wait in a queue bounded by `MAX_QUEUED`; beyond it the oldest are dropped and counted, and the
count is said (`dropped`), never silent. The feed's errors reach the reader of `batches()`, in order.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterator

from ..errors import warn
from .joint_state import POLL_SECONDS, Feed, JointStateSample

MAX_QUEUED = 100_000  # samples (about 100 s of a 1 kHz stream; a 29-joint sample is well under 1 kB)


class Prefetched:
    """`batches()` as the feed's, read ahead on a thread from construction on; `close()` ends both."""

    def __init__(self, feed: Feed, max_queued: int = MAX_QUEUED) -> None:
        self.feed, self.max_queued = feed, max_queued
        self.description = feed.description
        self.dropped = 0
        self._queue: deque[list[JointStateSample]] = deque()
        self._queued = 0
        self._done = False
        self._failure: BaseException | None = None
        self._ready = threading.Condition()
        self._thread = threading.Thread(target=self._read, name="urdf-pipeline-live-feed", daemon=True)
        self._thread.start()  # reading begins now: the caller may be busy before it asks for the first batch

    def batches(self) -> Iterator[list[JointStateSample]]:
        try:
            while True:
                with self._ready:
                    self._ready.wait_for(lambda: self._queue or self._done, timeout=POLL_SECONDS)
                    batch = self._queue.popleft() if self._queue else []
                    self._queued -= len(batch)
                    if not batch and self._done:
                        break
                yield batch
        finally:
            self.close()
        if self._failure is not None:
            raise self._failure

    def close(self) -> None:
        self.feed.close()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join()

    def _read(self) -> None:
        try:
            for batch in self.feed.batches():
                if batch:
                    self._put(batch)
        except BaseException as exc:  # noqa: BLE001 - handed to the reader of batches(), which raises it
            self._failure = exc
        finally:
            with self._ready:
                self._done = True
                self._ready.notify_all()

    def _put(self, batch: list[JointStateSample]) -> None:
        dropped = 0
        with self._ready:
            self._queue.append(batch)
            self._queued += len(batch)
            while self._queued > self.max_queued and len(self._queue) > 1:
                oldest = self._queue.popleft()
                self._queued -= len(oldest)
                dropped += len(oldest)
            self._ready.notify_all()
        if dropped:
            self.dropped += dropped
            warn(f"live: the views fell behind {self.description}: dropped the {dropped} oldest samples waiting ({self.dropped} in all)")

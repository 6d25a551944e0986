"""A feed read on a thread of its own, so the stream is drained while the views are busy (compiling the plan at the
first message, sending a robot's meshes): a Foxglove server keeps about a thousand messages per client and drops the
oldest beyond, silently, so a client that stops reading for a second at 1 kHz would lose samples nobody is told of.

Here the samples wait in `WaitingSamples`, bounded in samples (`MAX_QUEUED`) and in bytes (`MAX_QUEUED_BYTES`: a
sample of 4,096 joints is 100 times a 29-joint one); beyond either the oldest are dropped and counted, and the count
is said (`dropped`, a line per 5 s at most), never silent. The feed's errors reach the reader of `batches()`, in order.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Iterator

from ..errors import warn
from .joint_state import POLL_SECONDS, Feed, JointStateSample, names_bytes

MAX_QUEUED = 100_000  # samples (about 100 s of a 1 kHz stream)
MAX_QUEUED_BYTES = 64 * 1024 * 1024  # what they hold (a 29-joint sample: about 450 bytes, its names shared)
WARN_SECONDS = 5.0  # samples dropped are said at most once per window (the first at once); the last line counts all
JOIN_SECONDS = 1.0  # how long close() waits for the reading thread
SAMPLE_BYTES = 200  # a sample's own objects besides its positions' values (the dataclass, the array, the ints)


class WaitingSamples:
    """Batches of samples in arrival order, bounded in samples and in bytes: each sample's positions and objects,
    and each distinct names tuple once while a sample holding it waits (the feeds intern them, so a robot's one
    order costs once). Past a bound the oldest batches are dropped (the newest is always kept: the feeds bound it)."""

    def __init__(self, max_samples: int = MAX_QUEUED, max_bytes: int = MAX_QUEUED_BYTES) -> None:
        self.max_samples, self.max_bytes = max_samples, max_bytes
        self.samples = self.bytes = 0
        self._batches: deque[list[JointStateSample]] = deque()
        self._names: dict[int, list[int]] = {}  # id of a waiting names tuple -> [samples holding it, its bytes]

    def __bool__(self) -> bool:
        return bool(self._batches)

    def append(self, batch: list[JointStateSample]) -> int:
        """Adds the batch; the number of samples dropped to stay within the bounds."""
        self._batches.append(batch)
        self.samples += len(batch)
        for sample in batch:
            self.bytes += SAMPLE_BYTES + sample.positions.nbytes
            held = self._names.get(id(sample.names))
            if held is None:
                held = self._names[id(sample.names)] = [0, names_bytes(sample.names)]
                self.bytes += held[1]
            held[0] += 1
        dropped = 0
        while (self.samples > self.max_samples or self.bytes > self.max_bytes) and len(self._batches) > 1:
            dropped += len(self.popleft())
        return dropped

    def popleft(self) -> list[JointStateSample]:
        batch = self._batches.popleft()
        self.samples -= len(batch)
        for sample in batch:
            self.bytes -= SAMPLE_BYTES + sample.positions.nbytes
            held = self._names[id(sample.names)]
            held[0] -= 1
            if not held[0]:
                del self._names[id(sample.names)]
                self.bytes -= held[1]
        return batch

    def take_all(self) -> list[JointStateSample]:
        """Every waiting sample, in order; empty after."""
        taken: list[JointStateSample] = []
        while self._batches:
            taken += self.popleft()
        return taken


class Prefetched:
    """`batches()` as the feed's, read ahead on a thread from construction on; `close()` ends both."""

    def __init__(self, feed: Feed, max_queued: int = MAX_QUEUED, max_bytes: int = MAX_QUEUED_BYTES) -> None:
        self.feed = feed
        self.description = feed.description
        self.dropped = 0
        self._unsaid, self._said = 0, -WARN_SECONDS  # dropped since the last line, and when it was said
        self._waiting = WaitingSamples(max_queued, max_bytes)
        self._done = False
        self._failure: BaseException | None = None
        self._ready = threading.Condition()
        self._thread = threading.Thread(target=self._read, name="urdf-pipeline-live-feed", daemon=True)
        self._thread.start()  # reading begins now: the caller may be busy before it asks for the first batch

    def batches(self) -> Iterator[list[JointStateSample]]:
        try:
            while True:
                with self._ready:
                    self._ready.wait_for(lambda: self._waiting or self._done, timeout=POLL_SECONDS)
                    batch = self._waiting.popleft() if self._waiting else []
                    if not batch and self._done:
                        break
                yield batch
        finally:
            self.close()
        if self._failure is not None:
            raise self._failure

    def close(self) -> None:
        """The feed closed and its thread waited for, JOIN_SECONDS at most: every feed ends a wait under way when
        closed, but a host name being resolved cannot be cut short, and the caller must end promptly (the thread is a
        daemon, and touches nothing but this object)."""
        self.feed.close()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(JOIN_SECONDS)

    def _read(self) -> None:
        try:
            for batch in self.feed.batches():
                if batch:
                    self._put(batch)
        except BaseException as exc:  # handed to the reader of batches(), which raises it
            self._failure = exc
        finally:
            with self._ready:
                self._done = True
                self._ready.notify_all()

    def _put(self, batch: list[JointStateSample]) -> None:
        with self._ready:
            dropped = self._waiting.append(batch)
            self._ready.notify_all()
        if dropped:
            self.dropped += dropped
            self._unsaid += dropped
            if time.monotonic() - self._said >= WARN_SECONDS:  # a line per window at most: a flood says once in a while
                self._said = time.monotonic()
                warn(
                    f"live: the views fell behind {self.description}: dropped the {self._unsaid} oldest samples waiting ({self.dropped} in all)"
                )
                self._unsaid = 0

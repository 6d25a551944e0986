"""The feed read ahead on a thread: samples wait in a bounded queue while the views are busy; beyond the bound the
oldest are dropped and said, never silently; the feed's error reaches the reader."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator

import numpy as np
import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.live_views.joint_state import JointStateSample
from urdf_pipeline.live_views.prefetch import Prefetched, WaitingSamples


def sample(k: int) -> JointStateSample:
    return JointStateSample("/joint_states", ("a",), np.array([float(k)]), k, k, k, k)


class ListFeed:
    """A feed of given batches, then (optionally) an error: the protocol's shape, in memory."""

    description = "a list"

    def __init__(self, batches: list[list[JointStateSample]], failure: UserError | None = None) -> None:
        self.given, self.failure = batches, failure
        self.all_read = threading.Event()
        self.closed = threading.Event()

    def batches(self) -> Iterator[list[JointStateSample]]:
        for batch in self.given:
            if self.closed.is_set():
                return
            yield batch
        self.all_read.set()
        if self.failure is not None:
            raise self.failure

    def close(self) -> None:
        self.closed.set()


def test_samples_arrive_in_order() -> None:
    feed = ListFeed([[sample(k), sample(k + 1)] for k in range(0, 100, 2)])
    got = [s.header_ns for batch in Prefetched(feed).batches() for s in batch]
    assert got == list(range(100))


def test_a_slow_reader_drops_the_oldest_and_says_so_once_in_a_while(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="urdf_pipeline")
    feed = ListFeed([[sample(k)] for k in range(50)])
    ahead = Prefetched(feed, max_queued=10)
    reader = ahead.batches()
    assert feed.all_read.wait(30)  # the reader was busy: nothing taken while the feed ran
    got = [s.header_ns for batch in reader for s in batch]
    assert got == list(range(40, 50)) and ahead.dropped == 40
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and "fell behind a list: dropped the 1 oldest samples waiting (1 in all)" in said[0]  # once per 5 s


def test_the_feeds_error_reaches_the_reader_after_its_samples() -> None:
    feed = ListFeed([[sample(0)], [sample(1)]], UserError("lost ws://x after 3 reconnects"))
    got: list[int] = []
    with pytest.raises(UserError, match="lost ws://x"):
        for batch in Prefetched(feed).batches():
            got += [s.header_ns for s in batch]
    assert got == [0, 1]


def wide_sample(k: int, names: tuple[str, ...]) -> JointStateSample:
    return JointStateSample("/joint_states", names, np.zeros(len(names)), k, k, k, k)


def test_the_queue_is_bounded_in_bytes_with_each_names_list_counted_once() -> None:
    """4,096 joints with 200-character names: a sample of fresh names costs about 1 MB, one of a kept order 33 kB."""
    names = tuple(f"{j:04d}" + "x" * 196 for j in range(4096))
    waiting = WaitingSamples(max_samples=100_000, max_bytes=8 * 1024 * 1024)
    dropped = sum(waiting.append([wide_sample(k, tuple(list(names)))]) for k in range(20))  # a new tuple each time
    assert waiting.bytes <= 8 * 1024 * 1024 and waiting.samples < 10 and dropped == 20 - waiting.samples
    shared = WaitingSamples(max_samples=100_000, max_bytes=8 * 1024 * 1024)
    assert sum(shared.append([wide_sample(k, names)]) for k in range(200)) == 0  # one names list: 200 samples fit
    assert shared.bytes < 8 * 1024 * 1024
    assert [s.header_ns for s in shared.take_all()] == list(range(200)) and shared.bytes == 0 and not shared


def test_a_slow_reader_of_wide_samples_keeps_the_newest_within_the_bytes_bound(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="urdf_pipeline")
    feed = ListFeed([[wide_sample(k, tuple(f"j{k}-{j}" + "y" * 200 for j in range(4096)))] for k in range(30)])
    ahead = Prefetched(feed, max_bytes=4 * 1024 * 1024)
    reader = ahead.batches()
    assert feed.all_read.wait(30)
    got = [s.header_ns for batch in reader for s in batch]
    assert got == list(range(30 - len(got), 30)) and len(got) < 10 and ahead.dropped == 30 - len(got)

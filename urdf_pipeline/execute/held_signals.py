"""Ctrl-C and SIGTERM taken between our own statements, never inside a wait of the standard library.

Python raises a signal handler's exception wherever the main thread is, also inside a lock wait, and some waits are
then left broken: concurrent.futures' `wait`, `submit` and `Future.result` may leave a lock held (the interpreter then
hangs at exit joining the pool's manager thread, seen under load after Ctrl-C); `Thread.start` raises while the
thread it started runs on; and on Python 3.11 and older an interrupted `Thread.join` marks the thread stopped while
it still runs (CPython gh-90882), so every later `join` returns at once and `is_alive()` says False (seen: a cancelled
writer was not waited for, and Rerun's threads aborted the process at exit)."""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

STOPPING = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def deferred_signals() -> Iterator[list[int]]:
    """SIGINT and SIGTERM that arrive inside the block are recorded (in the list it yields) and delivered to their own
    handlers when it ends, so the KeyboardInterrupt is raised in our code, never inside a library holding a lock.

    A signal this process ignores stays ignored (a pool worker ignores both: the main process stops it), and one whose
    handler was set outside Python is left alone (it cannot be given back). Outside the main thread (where no handler
    runs) this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield []
        return
    received: list[int] = []
    previous: dict[int, Callable[[int, FrameType | None], Any] | int] = {}
    try:
        for stopping in STOPPING:
            handler = signal.getsignal(stopping)
            if handler is not None and handler != signal.SIG_IGN:
                previous[int(stopping)] = handler  # before it is replaced: a signal between the two lines finds it given back
                signal.signal(stopping, lambda number, frame: received.append(number))
        yield received
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if received:
        first = previous[received[0]]
        if callable(first):
            first(received[0], None)  # default_int_handler raises KeyboardInterrupt; handle_sigterm's raises errors.Stopped
        elif first == signal.SIG_DFL:
            signal.raise_signal(received[0])

"""Ctrl-C and SIGTERM for the whole process, the one place every stage takes them from.

SIGTERM (CI cancellation, `timeout`, `kill`) stops a command as Ctrl-C does, as a KeyboardInterrupt (`Stopped`):
Python's default ends the process at once, leaving workers, partial files and temporary folders behind. The exit
point turns either into `errors.ExitCode.for_signal` (130, 143). Python raises a handler's exception wherever the main
thread is, also inside a lock wait, and some waits are then left broken: concurrent.futures' `wait`, `submit` and
`Future.result` may leave a lock held (the interpreter hangs at exit), `Thread.start` raises while its thread runs on,
and on Python 3.11 an interrupted `Thread.join` marks a running thread stopped (CPython gh-90882). So such waits run
inside `deferred_signals`, and cleanup that a second Ctrl-C must not cut short inside `held_off`.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

STOPPING = (signal.SIGINT, signal.SIGTERM)


class Stopped(KeyboardInterrupt):
    """A command stopped by a signal: SIGINT (Ctrl-C) or SIGTERM (raised in the main thread by `sigterm_kept`, or by
    a command that ended its own work on the signal, such as `live`). `said`: the command has said its own last line,
    so the exit point adds none."""

    def __init__(self, signum: int, said: bool = False) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)
        self.said = said


def stop_signal(interrupt: BaseException) -> int:
    """The signal a KeyboardInterrupt stands for: a `Stopped`'s own, else SIGINT (Python's Ctrl-C)."""
    return interrupt.signum if isinstance(interrupt, Stopped) else int(signal.SIGINT)


def signal_name(signum: int) -> str:
    """What a person calls it: "Ctrl-C", "SIGTERM"."""
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name


def _raise_stopped(signum: int, frame: FrameType | None) -> None:
    signal.signal(signum, signal.SIG_IGN)  # a second SIGTERM must not break the cleanup the first one started
    raise Stopped(signum)


@contextmanager
def sigterm_kept(stops: bool = False) -> Iterator[None]:
    """The SIGTERM handler given back as the block ends (a library may replace it: Ray does; tests call the command line
    in-process). `stops`: meanwhile, SIGTERM raises `Stopped` (handlers can only be set in the main thread)."""
    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGTERM)
    if stops and main:
        signal.signal(signal.SIGTERM, _raise_stopped)
    try:
        yield
    finally:
        if main and previous is not None and signal.getsignal(signal.SIGTERM) is not previous:  # None: set outside Python
            signal.signal(signal.SIGTERM, previous)


@contextmanager
def deferred_signals() -> Iterator[list[int]]:
    """SIGINT and SIGTERM that arrive inside the block are recorded (in the list it yields) and delivered to their own
    handlers when it ends, so the KeyboardInterrupt is raised in our code, never inside a library holding a lock. A
    signal ignored stays ignored, one whose handler was set outside Python is left alone (it cannot be given back);
    outside the main thread (where no handler runs) this does nothing."""
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
            first(received[0], None)  # default_int_handler raises KeyboardInterrupt; sigterm_kept's raises Stopped
        elif first == signal.SIG_DFL:
            signal.raise_signal(received[0])


def ignore_stop_signals() -> dict[int, Any]:
    """SIGINT and SIGTERM ignored from now on (a pool worker: the main process stops it); the handlers they had."""
    return {int(number): signal.signal(number, signal.SIG_IGN) for number in STOPPING}


@contextmanager
def held_off(ignored: bool = False) -> Iterator[None]:
    """SIGINT and SIGTERM blocked while the block runs, delivered as it ends: cleanup that a second Ctrl-C must not cut
    short. `ignored`: also ignored meanwhile (in the main thread), so that a process started in the block begins with
    both ignored."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOPPING)
    handlers = ignore_stop_signals() if ignored and threading.current_thread() is threading.main_thread() else {}
    try:
        yield
    finally:
        for number, handler in handlers.items():
            signal.signal(number, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)

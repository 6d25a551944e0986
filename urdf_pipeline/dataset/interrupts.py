"""SIGTERM (CI cancellation, `timeout`, `kill`) stops a run as Ctrl-C does: as a KeyboardInterrupt in the main process.

Python's default for SIGTERM ends the process at once: worker processes, partial files and temporary folders are left
behind and no summary is printed. Raised as an exception instead, it takes the path Ctrl-C takes (workers stopped,
partial files removed, the manifest true to the complete files, the summary printed). The exit status is the CLI's
exit point's (`errors.ExitCode.for_signal`: 130 after Ctrl-C, 143 after SIGTERM), for every command.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType

from ..errors import Stopped


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    signal.signal(signum, signal.SIG_IGN)  # a second SIGTERM must not break the cleanup the first one started
    raise Stopped(signum)


def handle_sigterm() -> None:
    """From now on, SIGTERM raises `errors.Stopped` in the main thread (signal handlers can only be set there)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _raise_terminated)


def keep_sigterm_handler() -> object:
    """The current SIGTERM handler, to give back to `restore_sigterm_handler` after a library replaced it (Ray does)."""
    return signal.getsignal(signal.SIGTERM)


def restore_sigterm_handler(handler: object) -> None:
    if handler is None:  # set outside Python: nothing to give back
        return
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGTERM) is not handler:
        signal.signal(signal.SIGTERM, handler)  # type: ignore[arg-type]


def signal_name(signum: int) -> str:
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name

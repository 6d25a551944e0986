"""The child processes the tool starts (the headless viewer for pictures, the `rerun` binary that serves the web
viewer's files): each in a session of its own, dying with this process, and stopped whole."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Callable


def die_with_parent() -> Callable[[], None] | None:
    """A `preexec_fn` for Linux: the child gets SIGTERM when this process dies, even by SIGKILL (prctl
    PR_SET_PDEATHSIG), so no viewer outlives a killed command. None elsewhere."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)  # loaded here, in the parent: the child only calls it

    def arrange() -> None:
        libc.prctl(1, signal.SIGTERM)

    return arrange


def stop_session(process: subprocess.Popen[bytes]) -> None:
    """SIGTERM to the child's session, SIGKILL after 5 s, with Ctrl-C and SIGTERM held off meanwhile (a second Ctrl-C
    must not leave the child running)."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        for sent in (signal.SIGTERM, signal.SIGKILL):
            if process.poll() is not None:
                return
            try:
                os.killpg(process.pid, sent)
            except ProcessLookupError:
                return
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(5.0)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)

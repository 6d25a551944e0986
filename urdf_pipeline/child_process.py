"""The child processes the tool starts (the headless viewer for pictures, the `rerun` binary that serves the web
viewer's files): each in a session of its own, dying with this process, and stopped whole. And the bounds a child that
reads a stranger's file sets on itself (the xacro, MJCF and MCAP readers: `limit_this_process`), with the bounds the
person running the tool may raise from the environment (`bound_from_environment`), never a config."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping

from .errors import UserError, Where, shown


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


def limit_this_process(limits: Mapping[str, int], threads: bool = False) -> None:
    """Bound this process before it reads a stranger's file: address space, CPU seconds, the size of any file written
    (stdout is one), no core dump, and no child process, nor (unless `threads`: Rerun's reader runs its own) thread:
    Linux counts both against RLIMIT_NPROC."""
    import resource

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # an oversized write fails (EFBIG) instead of killing silently
    bounds = [
        (resource.RLIMIT_AS, limits["memory_bytes"]),
        (resource.RLIMIT_CPU, limits["cpu_seconds"]),
        (resource.RLIMIT_FSIZE, limits["output_bytes"]),
        (resource.RLIMIT_CORE, 0),
    ]
    if not threads:
        bounds.append((resource.RLIMIT_NPROC, 0))
    for kind, value in bounds:
        with contextlib.suppress(ValueError, OSError):  # a limit the platform lacks or refuses stays as it was
            resource.setrlimit(kind, (value, value))


def bound_from_environment(name: str, default: float, where: Where | None = None) -> float:
    """A positive number the person running the tool may set in the environment variable `name` to raise (or lower) a
    child's bound; `default` when unset. A UserError at `where`, naming the variable, for anything else (NaN too)."""
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0 or value == float("inf"):
        raise UserError(f"{name}='{shown(text)}' must be a positive number", where)
    return value

"""The bounds a child process of ours sets on itself before it reads a stranger's file (the xacro and MJCF sandboxes):
address space, CPU seconds, the size of any file written, no core dump, no process of its own."""

from __future__ import annotations

import contextlib
from collections.abc import Mapping


def limit_this_process(limits: Mapping[str, int]) -> None:
    """Bound this process: address space, CPU seconds, size of any file written (stdout is one), no children."""
    import resource
    import signal

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # an oversized write fails (EFBIG) instead of killing silently
    for kind, value in (
        (resource.RLIMIT_AS, limits["memory_bytes"]),
        (resource.RLIMIT_CPU, limits["cpu_seconds"]),
        (resource.RLIMIT_FSIZE, limits["output_bytes"]),
        (resource.RLIMIT_CORE, 0),
        (resource.RLIMIT_NPROC, 0),
    ):
        with contextlib.suppress(ValueError, OSError):  # a limit the platform lacks or refuses stays as it was
            resource.setrlimit(kind, (value, value))

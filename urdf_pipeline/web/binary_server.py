"""The installed rerun-sdk's `rerun` binary serving its web viewer for a moment, so `viewer_assets` can copy it.

The child listens on 127.0.0.1 only (`--bind`; its default is every interface), on ports the system picks (0), in a
session of its own (Ctrl-C in the terminal reaches us, not it), its output in a log file it also tells its port in;
on Linux it is asked to die with us. It is stopped whatever way the block ends.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

from ..errors import UserError
from ..process import start_viewer, stop_session, viewer_binary

STARTUP_SECONDS = 30.0
HOSTING = re.compile(r"Hosting a web-viewer at http://127\.0\.0\.1:(\d+)")


def rerun_binary(wanted: str) -> str:
    """The viewer binary of rerun-sdk (`process.viewer_binary`), checked to be release `wanted` (`rerun --version`)."""
    binary = viewer_binary("serve Rerun's web viewer")
    try:
        said = subprocess.run([binary, "--version"], capture_output=True, text=True, timeout=60, env=_environment()).stdout
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise UserError(f"cannot run the rerun binary {binary}: {exc}") from None
    found = said.split()[1] if len(said.split()) > 1 else said.strip()
    if found != wanted:
        raise UserError(
            f"the rerun binary {binary} is release {found or 'unknown'}, not the installed rerun-sdk {wanted}; reinstall rerun-sdk"
        )
    return binary


def _environment() -> dict[str, str]:
    """`CI` keeps Rerun's usage analytics off (its native pipeline's own rule); `RERUN_APP_ONLY` its first-run prompt."""
    return {**os.environ, "CI": "1", "RERUN_APP_ONLY": "true", "RUST_LOG": "info"}


@contextlib.contextmanager
def serving_web_viewer(binary: str, folder: Path) -> Iterator[int]:
    """`rerun --serve-web` on 127.0.0.1 for the duration of the block; yields the web viewer's HTTP port."""
    log_path = folder / "rerun.log"
    args = ["--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", "0", "--port", "0"]
    with open(log_path, "wb") as log:
        process = start_viewer(binary, args, log, folder, _environment())
    try:
        yield _announced_port(process, log_path)
    finally:
        stop_session(process)


def _announced_port(process: subprocess.Popen[bytes], log_path: Path) -> int:
    """The port the binary says it hosts the web viewer on (its log line), once it says so."""
    deadline = time.monotonic() + STARTUP_SECONDS
    while True:
        text = log_path.read_text(encoding="utf-8", errors="replace")
        found = HOSTING.search(text)
        if found:
            return int(found.group(1))
        if process.poll() is not None or time.monotonic() > deadline:
            last = [line for line in text.splitlines() if line.strip()][-1:] or ["(no output)"]
            state = f"stopped (exit status {process.returncode})" if process.returncode is not None else "did not start"
            raise UserError(f"the rerun binary serving the web viewer {state} within {STARTUP_SECONDS:.0f} s: {last[0][:300]}")
        time.sleep(0.05)

"""The Rerun viewer as a process, for `run`, `live` and `urdf_pipeline.live`: its binary, its address on this machine,
a `--connect URL` checked (its form, a viewer listening there: a TCP connect of a few seconds at most), or a viewer
started (`--spawn`, one way for all) and seen to stay up, settled before any work.

Without these checks Rerun's client would be handed an unreachable address after the run: it retries for 7 s, logs
two ERROR lines of its own, and waits 5 s more at shutdown. A viewer that cannot start (no screen here) exits within
milliseconds of opening its port, so a started viewer counts as up only once it has stayed up for `SETTLE_SECONDS`.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO
from urllib.parse import urlsplit

from ..errors import UserError, Where, shown
from .children import ANSI_ESCAPE, die_with_parent

EXPECTED_FORM = "rerun+http://HOST:PORT/proxy"
DEFAULT_PORT = 9876  # where a viewer started with plain `rerun` listens, and where --spawn starts one
SCHEMES = ("rerun+http", "rerun+https", "rerun")  # what Rerun's client takes (rerun:// is rerun+https://)
CONNECT_SECONDS = 3.0  # the TCP connect to a --connect address
STARTUP_SECONDS = 10.0  # a spawned viewer opens its port within this
SETTLE_SECONDS = 1.0  # ... and is still running this long after
POLL_SECONDS = 0.05
LOG_TAIL_BYTES = 65_536  # of the viewer's log, read for the reason it stopped
CONNECT_OPTION = Where(Path("--connect"), 0)
SPAWN_OPTION = Where(Path("--spawn"), 0)
SCREENS = ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")  # a display server on Linux, for a viewer's window


def viewer_url(port: int | None = None) -> str:
    """The address of a viewer on this machine at `port` (default `DEFAULT_PORT`)."""
    return f"rerun+http://127.0.0.1:{DEFAULT_PORT if port is None else port}/proxy"


def viewer_binary(doing: str, where: Where | None = None) -> str:
    """The viewer that ships in rerun-sdk (rerun_cli's binary: the release of the SDK that sends, not the Python shim
    that would start it), else a `rerun` beside this Python, else one on PATH; a user error (cannot `doing`) if none."""
    executable = "rerun.exe" if sys.platform.startswith("win") else "rerun"
    spec = importlib.util.find_spec("rerun_cli")
    candidates = [Path(spec.origin).parent / executable] if spec is not None and spec.origin else []
    candidates.append(Path(sys.executable).parent / executable)
    for candidate in candidates:
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    found = shutil.which(executable)
    if found is None:
        raise UserError(f"cannot {doing}: rerun-sdk's `rerun` binary is missing (reinstall rerun-sdk)", where)
    return found


def _listening(host: str, port: int, timeout: float) -> OSError | None:
    """None when something accepts a TCP connection at host:port within `timeout` seconds, else why not."""
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as error:
        return error
    return None


def require_viewer(url: str) -> str:
    """`--connect URL`: its form (the one Rerun's client takes), then a viewer listening there (within `CONNECT_SECONDS`);
    returns the URL."""
    wrong = f"{shown(url)} is not a viewer address; expected {EXPECTED_FORM} (a viewer started with `rerun` listens at {viewer_url()})"
    try:
        parts = urlsplit(url)
        host, port = parts.hostname, parts.port
    except ValueError:  # a port that is no number, or out of range
        raise UserError(wrong, CONNECT_OPTION) from None
    if parts.scheme not in SCHEMES or not host or port is None or parts.path != "/proxy" or parts.query or parts.fragment:
        raise UserError(wrong, CONNECT_OPTION)
    error = _listening(host, port, CONNECT_SECONDS)
    if error is not None:
        reason = "timed out" if isinstance(error, TimeoutError) else (error.strerror or str(error))
        raise UserError(
            f"no Rerun viewer at {shown(url)} ({host}:{port}: {reason}); start one there (`rerun --port {port}`), or use --spawn",
            CONNECT_OPTION,
        )
    return url


def spawn_viewer(port: int | None = None) -> str:
    """`--spawn` (and `urdf_pipeline.live`'s spawn): the URL of a viewer on this machine, one started now (detached: it
    stays when the command ends) unless one already listens on `port` (default `DEFAULT_PORT`). A viewer that cannot
    start is a user error with its own reason, in a few seconds; no screen here, at once."""
    port = DEFAULT_PORT if port is None else port
    url = viewer_url(port)
    if _listening("127.0.0.1", port, CONNECT_SECONDS) is None:
        return url  # a viewer already listening there is reused, as Rerun's own spawn does
    if sys.platform.startswith("linux") and not any(os.environ.get(name) for name in SCREENS):  # its window cannot open
        raise UserError(
            "cannot start the Rerun viewer: no screen here (neither DISPLAY nor WAYLAND_DISPLAY is set); run `rerun` where "
            "there is one and send to it with --connect URL, or run without --spawn and open the written .rrd files there",
            SPAWN_OPTION,
        )
    executable = viewer_binary("start the Rerun viewer", SPAWN_OPTION)
    with tempfile.TemporaryFile() as log:  # unlinked already: the detached viewer's log leaves no file behind
        try:  # detached: the viewer is the user's now
            process = start_viewer(executable, ["--port", str(port), "--memory-limit", "75%", "--expect-data-soon"], log, detached=True)
        except OSError as error:
            raise UserError(f"cannot start the Rerun viewer {shown(executable)}: {error.strerror or error}", SPAWN_OPTION) from None
        _wait_until_up(process, port, log)
    return url


def start_viewer(
    executable: str, args: Sequence[str], log: IO[bytes], cwd: Path | None = None, env: Mapping[str, str] = {}, detached: bool = False
) -> subprocess.Popen[bytes]:
    """The viewer binary with `args`, in a session of its own (Ctrl-C in the terminal reaches us, not it), its output in
    `log`, without Rerun's first-run prompt; dying with this process unless `detached`."""
    environment = {**os.environ, "RERUN_APP_ONLY": "true", **env}
    return subprocess.Popen(
        [executable, *args], stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, cwd=cwd, env=environment,
        start_new_session=True, preexec_fn=None if detached else die_with_parent(),
    )  # fmt: skip


def _wait_until_up(process: subprocess.Popen[bytes], port: int, log: IO[bytes]) -> None:
    """Up: its port accepts and the process is still running `SETTLE_SECONDS` later. Else it is stopped (when still
    running) and the reason is its last error line."""
    deadline = time.monotonic() + STARTUP_SECONDS
    opened: float | None = None
    while process.poll() is None:
        now = time.monotonic()
        if opened is None and _listening("127.0.0.1", port, POLL_SECONDS) is None:
            opened = now
        if opened is not None and now - opened >= SETTLE_SECONDS:
            return
        if now > deadline:
            process.kill()
            process.wait()
            raise UserError(
                f"the Rerun viewer did not start listening on port {port} within {STARTUP_SECONDS:.0f} s{log_reason(log)}", SPAWN_OPTION
            )
        time.sleep(POLL_SECONDS)
    raise UserError(f"the Rerun viewer stopped at its start (exit status {process.returncode}){log_reason(log)}", SPAWN_OPTION)


def log_reason(log: IO[bytes]) -> str:
    """`: REASON` from a viewer's log (its end): its `Error:` line, else its last ERROR log line, else its last line."""
    log.seek(0, os.SEEK_END)
    log.seek(max(log.tell() - LOG_TAIL_BYTES, 0))
    lines = [ANSI_ESCAPE.sub("", line).strip() for line in log.read(LOG_TAIL_BYTES).decode("utf-8", "replace").splitlines()]
    lines = [line for line in lines if line]
    chosen = next((line for line in reversed(lines) if line.startswith("Error:")), None)
    chosen = chosen or next((line for line in reversed(lines) if " ERROR " in line), None) or (lines[-1] if lines else "")
    return f": {shown(chosen.removeprefix('Error:').strip(), 300)}" if chosen else ""

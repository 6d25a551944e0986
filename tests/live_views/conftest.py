"""The real components the live-view tests start: Foxglove WebSocket servers (`tests/live_views/foxglove_server.py`)
and MCAP recorders (`tests/live_views/mcap_appender.py`) in child processes, each started by the test that needs it
(they start in well under a second) and always stopped after it."""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from urdf_pipeline.process.children import die_with_parent

from ..local_processes import free_port, stop

REPO = Path(__file__).resolve().parents[2]
START_SECONDS = 60.0  # generous: a loaded 2-core machine


@dataclass(frozen=True)
class FoxgloveServer:
    port: int
    process: subprocess.Popen[bytes]

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    def advertise(self) -> None:
        """Tells a server started with --advertise-on-input to advertise its topic now."""
        assert self.process.stdin is not None
        self.process.stdin.write(b"go\n")
        self.process.stdin.flush()

    def kill(self) -> None:
        """Gone at once, as a crashed driver or a robot switched off: no close frame, the port free again."""
        self.process.kill()
        self.process.wait()


def ready_line(process: subprocess.Popen[bytes], seconds: float = START_SECONDS) -> str:
    """The first line the child prints, waited for at most `seconds`."""
    assert process.stdout is not None
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        deadline = time.monotonic() + seconds
        while not selector.select(timeout=0.1):
            assert process.poll() is None, f"the server ended with {process.returncode} before it was ready"
            assert time.monotonic() < deadline, f"the server printed nothing within {seconds:.0f} s"
    return process.stdout.readline().decode().strip()


@pytest.fixture
def foxglove_server() -> Iterator[Callable[..., FoxgloveServer]]:
    """Starts a server: `start("--count", "40", port=P)` (the options of foxglove_server.py); each one the test
    started is stopped after it, whatever happened."""
    started: list[subprocess.Popen[bytes]] = []

    def start(*options: str, port: int | None = None) -> FoxgloveServer:
        port = port or free_port()
        process = subprocess.Popen(
            [sys.executable, "-m", "tests.live_views.foxglove_server", "--port", str(port), *options],
            cwd=REPO,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            preexec_fn=die_with_parent(),
        )
        started.append(process)
        assert ready_line(process) == f"ready {port}"
        return FoxgloveServer(port, process)

    yield start
    for process in started:
        stop(process)
        for stream in (process.stdin, process.stdout):
            if stream is not None:
                stream.close()


@pytest.fixture
def appender() -> Iterator[Callable[..., subprocess.Popen[bytes]]]:
    """Starts tests/live_views/mcap_appender.py on a file with options; every child is stopped and reaped after the test."""
    children: list[subprocess.Popen[bytes]] = []

    def start(path: Path, *options: str) -> subprocess.Popen[bytes]:
        command = [sys.executable, "-m", "tests.live_views.mcap_appender", str(path), *options]
        children.append(subprocess.Popen(command, cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)}))
        return children[-1]

    yield start
    for child in children:
        stop(child)

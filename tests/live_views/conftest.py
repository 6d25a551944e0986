"""Fixtures of the live-view tests: the real recorder and servers they start, stopped after each test."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from ..local_processes import stop

REPO = Path(__file__).resolve().parents[2]


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

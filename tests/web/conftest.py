"""Fixtures of the web tests: the viewer cache of the session (fetched from the rerun binary once), the demo's
recording, and for the browser tests ONE headless chromium and ONE `urdf-pipeline serve` for the whole session.

The browser tests skip, saying why, where no chromium can be had (make test installs Debian's when run as root).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from urdf_pipeline import cli
from urdf_pipeline.process.children import die_with_parent
from urdf_pipeline.web import CACHE_VARIABLE, ViewerAssets, viewer_assets

from ..conftest import REPO
from .devtools import Browser, chromium_binary

SERVE_SECONDS = 30


@pytest.fixture(scope="session")
def viewer_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ViewerAssets]:
    """A cache of the session's own (URDF_PIPELINE_WEB_CACHE), filled once from the rerun binary."""
    previous = os.environ.get(CACHE_VARIABLE)
    os.environ[CACHE_VARIABLE] = str(tmp_path_factory.mktemp("web-viewer-cache"))
    try:
        yield viewer_assets()
    finally:
        if previous is None:
            os.environ.pop(CACHE_VARIABLE, None)
        else:
            os.environ[CACHE_VARIABLE] = previous


@pytest.fixture(scope="session")
def demo_recording(examples_dir: Path) -> Path:
    """configs/demo.yaml run into the session's examples folder: its recording (and the blueprint beside it)."""
    assert cli.main(["run", str(examples_dir / "demo.yaml"), "--jobs", "1", "-q"]) == 0
    return examples_dir / "out" / "episode_000.rrd"


@pytest.fixture(scope="session")
def browser() -> Iterator[Browser]:
    """One headless chromium for the whole session (its own temporary profile)."""
    if chromium_binary() is None:
        pytest.skip("no chromium: install Debian's (apt-get install chromium; make test does it when run as root)")
    with Browser() as started:
        yield started


@dataclass(frozen=True)
class Served:
    """The session's `urdf-pipeline serve`: the folder it serves (sites go under it) and its URL."""

    root: Path
    url: str


@pytest.fixture(scope="session")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """`urdf-pipeline serve ROOT` as a user runs it (a child process); ROOT holds an index.html, and the tests put
    their sites in folders under it (so every site is served under a path prefix). Stopped by SIGTERM: exit 143."""
    root = tmp_path_factory.mktemp("www")
    (root / "index.html").write_text("<!doctype html><title>sites of the web tests</title>\n", encoding="utf-8")
    environment = {**os.environ, "PYTHONPATH": str(REPO)}
    process = subprocess.Popen(
        [sys.executable, "-m", "urdf_pipeline", "serve", str(root)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
        preexec_fn=die_with_parent(),  # killed outright, the test session takes its server with it
    )
    try:
        assert process.stdout is not None
        url = process.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), f"serve printed {url!r}; stderr: {process.stderr.read() if process.stderr else ''}"
        yield Served(root, url)
    finally:
        process.send_signal(signal.SIGTERM)
        code = process.wait(SERVE_SECONDS)
        assert code == 143, f"serve ended with {code} after SIGTERM"

"""`run --connect URL` to a real (headless) viewer: the check before the run finds it, and the segment arrives there
under its own application and recording ids."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from urdf_pipeline.render.headless_viewer import HeadlessViewer

from ..dataset_helpers import isolated_examples

pytestmark = [pytest.mark.usefixtures("renderer"), pytest.mark.usefixtures("allow_examples")]


def test_connect_sends_the_segment_to_a_listening_viewer(viewer: HeadlessViewer, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "connect", "demo.yaml")
    result = run_cli("run", str(config), "--connect", viewer.url)
    assert result.code == 0, result.err
    assert f"sent 1 segment(s) to the viewer at {viewer.url}" in result.err
    assert "ERROR" not in result.err
    wanted = "Recording:panda_demo:episode_000"
    deadline = time.monotonic() + 30  # a bound on a failure, not a timing assertion: the viewer loads what it was sent
    while wanted not in (ids := [r.store_id for r in viewer.client.get_state().recordings]) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert wanted in ids

"""LeRobot datasets on the Hugging Face Hub, through the real `huggingface_hub` client, offline (HF_HUB_OFFLINE=1)
against a Hub cache the tests lay out in the client's own layout: a revision (branch, tag, `revision:`, a sha) is
resolved to its commit at compile and the plan keeps the sha, so a run reads exactly what was planned even when the
branch moves; `validate` and `plan` need the metadata only; a revision or a file the cache does not hold is a clear
located error; an unpinned dataset is warned about; Hub files stay in the client's cache."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline import load
from urdf_pipeline.dataset import RunOptions, run_dataset

from ..lerobot_layouts import cached_names, hub_commit, lerobot_panda_config, write_dataset
from ..source_helpers import assert_panda_fk, random_panda_q

REPO = "robots/panda_pick"
URL = f"hf://datasets/{REPO}"
FIRST = hashlib.sha1(b"first commit").hexdigest()
SECOND = hashlib.sha1(b"second commit").hexdigest()
LENGTHS = [30, 25, 20]


@pytest.fixture
def hub(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty Hub cache the client reads offline; this run allows the `robots` organisation's datasets."""
    pytest.importorskip("huggingface_hub", reason="the hub extra: pip install 'urdf-pipeline[hub]'")
    cache = tmp_path / "hub-cache"
    cache.mkdir()
    monkeypatch.setenv("HF_HUB_CACHE", str(cache))
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf-home"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_URLS", "hf://datasets/robots/")
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(tmp_path / "download-cache"))
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(tmp_path))
    return cache


def _episodes(examples_dir: Path, seed: int) -> list[np.ndarray]:
    return [random_panda_q(examples_dir, frames, seed=seed + n) for n, frames in enumerate(LENGTHS)]


def _check(examples_dir: Path, stem: str, episodes: list[np.ndarray]) -> None:
    for episode, q in enumerate(episodes):
        recording = examples_dir / "out" / stem / f"episode_{episode:06d}.rrd"
        assert_panda_fk(examples_dir, recording, "frame_index", list(range(len(q))), q, [0, len(q) // 2, len(q) - 1])


@pytest.mark.parametrize("layout", ["v2.1", "v3"])
def test_a_branch_is_planned_at_its_commit_and_the_episodes_run_from_the_hub_cache(
    layout: str, hub: Path, examples_dir: Path, tmp_path: Path, run_cli
) -> None:
    episodes = _episodes(examples_dir, seed=80)
    write_dataset(tmp_path / "dataset", episodes, layout)
    hub_commit(hub, REPO, tmp_path / "dataset", FIRST, only="meta/")  # the cache holds the metadata only
    stem = f"lerobot_hub_{layout.replace('.', '_')}"
    config = lerobot_panda_config(examples_dir, stem, {"lerobot": f"{URL}@main"})

    checked = run_cli("validate", str(config))
    assert checked.code == 0 and "warning" not in checked.err, checked.err
    planned = run_cli("plan", str(config), "--format", "json")
    assert planned.code == 0 and f"{URL}@{FIRST}" in planned.out, "the plan keeps the commit the branch resolved to"

    missing = run_cli("run", str(config), "--jobs", "1")
    assert missing.code == 1
    data_file = "data/chunk-000/episode_000000.parquet" if layout == "v2.1" else "data/chunk-000/file-000.parquet"
    assert f"{URL}@{FIRST}/{data_file} is not in the local Hub cache" in missing.err and "HF_HUB_OFFLINE" in missing.err, missing.err

    hub_commit(hub, REPO, tmp_path / "dataset", FIRST)  # now the data too, as a download would leave it
    first = run_cli("run", str(config), "--jobs", "1")
    assert first.code == 0, first.err
    assert "urdf-pipeline-view-" not in first.err, "the reader is shown only the episodes whose files the view holds"
    _check(examples_dir, stem, episodes)
    assert cached_names(tmp_path / "download-cache") == [], "Hub files stay in the Hub client's cache"
    again = run_cli("run", str(config), "--jobs", "1")
    assert again.code == 0 and "up to date" in again.err, again.err


def test_an_unpinned_dataset_is_warned_about_and_a_revision_key_pins_it(hub: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    write_dataset(tmp_path / "dataset", _episodes(examples_dir, seed=90), "v2.1")
    hub_commit(hub, REPO, tmp_path / "dataset", FIRST, refs=("main", "v1.0", "release/2025"))
    config = lerobot_panda_config(examples_dir, "lerobot_hub_unpinned", {"lerobot": URL})
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err
    assert "warning:" in result.err and "sources.state.lerobot" in result.err and "pins no revision" in result.err
    assert f"{URL}@REV" in result.err and "revision: REV" in result.err, "the warning names the fix"

    config = lerobot_panda_config(examples_dir, "lerobot_hub_tag", {"lerobot": URL, "revision": "v1.0"})
    result = run_cli("plan", str(config), "--format", "json")
    assert result.code == 0 and "warning" not in result.err, result.err
    assert f"{URL}@{FIRST}" in result.out
    config = lerobot_panda_config(examples_dir, "lerobot_hub_sha", {"lerobot": f"{URL}@{FIRST}"})
    assert run_cli("validate", str(config)).code == 0
    config = lerobot_panda_config(examples_dir, "lerobot_hub_branch", {"lerobot": URL, "revision": "release/2025"})
    result = run_cli("plan", str(config), "--format", "json")
    assert result.code == 0 and f"{URL}@{FIRST}" in result.out, "a branch name with a slash, from refs/release/2025"


@pytest.mark.parametrize(
    ("revision", "says"),
    [
        ("v9", "cannot resolve revision v9 of hf://datasets/robots/panda_pick@v9: the local Hub cache"),
        ("f" * 40, "; it knows the revisions main, v1.0), and HF_HUB_OFFLINE=1 forbids downloading it"),
    ],
)
def test_a_revision_the_cache_does_not_hold_is_a_located_error(
    revision: str, says: str, hub: Path, examples_dir: Path, tmp_path: Path, run_cli
) -> None:
    write_dataset(tmp_path / "dataset", _episodes(examples_dir, seed=95), "v2.1")
    hub_commit(hub, REPO, tmp_path / "dataset", FIRST, refs=("main", "v1.0"))
    config = lerobot_panda_config(examples_dir, "lerobot_hub_unknown", {"lerobot": f"{URL}@{revision}"})
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "lerobot_hub_unknown.yaml:" in result.err and "sources.state.lerobot" in result.err and says in result.err, result.err
    if revision == "v9":
        assert "the cache knows main, v1.0" in result.err, "the revisions it could pin instead"


def test_a_run_reads_the_commit_that_was_planned_when_the_branch_moves(hub: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    before, after = _episodes(examples_dir, seed=100), _episodes(examples_dir, seed=200)
    write_dataset(tmp_path / "before", before, "v2.1")
    write_dataset(tmp_path / "after", after, "v2.1")
    hub_commit(hub, REPO, tmp_path / "before", FIRST)
    config = lerobot_panda_config(examples_dir, "lerobot_hub_moving", {"lerobot": f"{URL}@main"})
    plan = load(config)
    hub_commit(hub, REPO, tmp_path / "after", SECOND)  # main moves to a new commit after the plan was made

    finished = run_dataset(plan, RunOptions(1, "local", None, True))
    assert [r.status for r in finished.results] == ["written"] * 3, [r.reason for r in finished.results]
    _check(examples_dir, "lerobot_hub_moving", before)

    again = run_cli("run", str(config), "--jobs", "1")  # a new plan: the branch's new commit, new content hashes, rewritten
    assert again.code == 0 and "up to date" not in again.err, again.err
    _check(examples_dir, "lerobot_hub_moving", after)
    manifest = json.loads((examples_dir / "out" / "lerobot_hub_moving" / "lerobot_hub_moving.manifest.json").read_text())
    assert len(manifest["segments"]) == 3

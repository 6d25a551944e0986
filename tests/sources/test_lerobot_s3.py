"""LeRobot datasets on S3 (a real S3 endpoint: moto_server on 127.0.0.1), v2.1 and v3: `validate` and `plan` download
the metadata only (into the download cache), `run` fetches each episode's data file(s) and gives poses equal to
pinocchio's, a re-run downloads nothing, an episode object changed after the plan fails its segment by name, and keys
or templates that would leave the dataset's folder are refused."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline import load
from urdf_pipeline.dataset import RunOptions, run_dataset

from ..conftest import S3
from ..lerobot_layouts import cached_names, dataset_files, lerobot_panda_config, write_dataset
from ..source_helpers import assert_panda_fk, random_panda_q

LENGTHS = [40, 30, 20]


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "download-cache"
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(folder))
    views = tmp_path / "tmp"  # the runs' temporary folders (the episodes' views), to check none is left
    views.mkdir()
    monkeypatch.setenv("TMPDIR", str(views))
    monkeypatch.setattr(tempfile, "tempdir", str(views))
    return folder


def _episodes(examples_dir: Path, seed: int) -> list[np.ndarray]:
    return [random_panda_q(examples_dir, frames, seed=seed + n) for n, frames in enumerate(LENGTHS)]


def _upload(s3: S3, prefix: str, dataset: Path) -> None:
    for relative in dataset_files(dataset):
        s3.client().upload_file(str(dataset / relative), s3.bucket, f"{prefix}/{relative}")


@pytest.mark.parametrize("layout", ["v2.1", "v3"])
def test_an_s3_dataset_is_planned_from_its_metadata_and_run_from_the_cache(
    layout: str, s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli
) -> None:
    episodes = _episodes(examples_dir, seed=40)
    write_dataset(tmp_path / "dataset", episodes, layout)
    _upload(s3, "teams/so/pick", tmp_path / "dataset")
    stem = f"lerobot_s3_{layout.replace('.', '_')}"
    config = lerobot_panda_config(examples_dir, stem, {"lerobot": s3.url("teams/so/pick")})

    for command in ("validate", "plan"):
        result = run_cli(command, str(config))
        assert result.code == 0, result.err
    meta = ["episodes.jsonl", "info.json", "tasks.jsonl"] if layout == "v2.1" else ["file-000.parquet", "info.json", "tasks.parquet"]
    assert cached_names(cache) == meta, "validate and plan download the metadata a reader needs, no data, no statistics"
    planned = json.loads(run_cli("plan", str(config), "--format", "json").out)
    assert s3.url("teams/so/pick") in json.dumps(planned)

    first = run_cli("run", str(config), "--jobs", "1")
    assert first.code == 0, first.err
    assert "urdf-pipeline-view-" not in first.err, "the reader is shown only the episodes whose files the view holds"
    for episode, q in enumerate(episodes):
        recording = examples_dir / "out" / stem / f"episode_{episode:06d}.rrd"
        assert_panda_fk(examples_dir, recording, "frame_index", list(range(len(q))), q, [0, len(q) // 2, len(q) - 1])
    data = ["episode_000000.parquet", "episode_000001.parquet", "episode_000002.parquet"]
    downloaded = sorted(cached_names(cache))
    assert downloaded == sorted(meta + (data if layout == "v2.1" else ["file-000.parquet", "file-001.parquet"]))
    assert not list((tmp_path / "tmp").glob("urdf-pipeline-view-*")), "each episode's view is removed after its segment"

    mtimes = {p: p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file() and not p.name.startswith(".")}
    again = run_cli("run", str(config), "--jobs", "1")
    assert again.code == 0 and "up to date" in again.err, again.err
    assert {p: p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file() and not p.name.startswith(".")} == mtimes


def test_one_episode_downloads_only_its_own_data_file(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    episodes = _episodes(examples_dir, seed=50)
    write_dataset(tmp_path / "dataset", episodes, "v3")
    _upload(s3, "v3/one", tmp_path / "dataset")
    config = lerobot_panda_config(examples_dir, "lerobot_s3_one", {"lerobot": s3.url("v3/one"), "episode": 2})
    result = run_cli("run", str(config), "--jobs", "1")
    assert result.code == 0, result.err
    assert "file-001.parquet" in cached_names(cache) and cached_names(cache).count("file-000.parquet") == 1  # the meta one
    q = episodes[2]
    recording = examples_dir / "out" / "lerobot_s3_one" / "episode_000002.rrd"
    assert_panda_fk(examples_dir, recording, "frame_index", list(range(len(q))), q, [0, len(q) - 1])


def test_an_episode_object_changed_after_planning_fails_its_segment_by_name(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    episodes = _episodes(examples_dir, seed=60)
    write_dataset(tmp_path / "dataset", episodes, "v2.1")
    _upload(s3, "changing", tmp_path / "dataset")
    config = lerobot_panda_config(examples_dir, "lerobot_s3_changed", {"lerobot": s3.url("changing")})
    plan = load(config)
    episodes[1] = episodes[1][::-1].copy()
    write_dataset(tmp_path / "later", episodes, "v2.1")
    key = "changing/data/chunk-000/episode_000001.parquet"
    s3.client().upload_file(str(tmp_path / "later" / "data" / "chunk-000" / "episode_000001.parquet"), s3.bucket, key)

    finished = run_dataset(plan, RunOptions(1, "local", None, True))
    assert [r.status for r in finished.results] == ["written", "failed", "written"]
    reason = finished.results[1].reason
    assert "changed after it was planned" in reason and s3.url(key) in reason, reason
    assert "episode_000001.parquet" not in cached_names(cache), "the refused download left nothing that counts"


def test_keys_and_templates_that_leave_the_dataset_are_refused(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    write_dataset(tmp_path / "dataset", _episodes(examples_dir, seed=70), "v2.1")
    _upload(s3, "hostile", tmp_path / "dataset")
    s3.client().put_object(Bucket=s3.bucket, Key="hostile/meta/episodes/../../../../x.parquet", Body=b"PAR1")
    config = lerobot_panda_config(examples_dir, "lerobot_s3_hostile", {"lerobot": s3.url("hostile")})
    result = run_cli("validate", str(config))
    assert result.code == 1 and "does not name a place inside the dataset's folder" in result.err, result.err
    assert "sources.state.lerobot" in result.err

    info = json.loads((tmp_path / "dataset" / "meta" / "info.json").read_text())
    info["data_path"] = "../elsewhere/{episode_index}.parquet"
    s3.client().put_object(Bucket=s3.bucket, Key="template/meta/info.json", Body=json.dumps(info).encode())
    config = lerobot_panda_config(examples_dir, "lerobot_s3_template", {"lerobot": s3.url("template")})
    result = run_cli("validate", str(config))
    assert result.code == 1 and "must stay inside the dataset" in result.err and s3.url("template/meta/info.json") in result.err


def test_a_prefix_without_a_dataset_is_named(s3: S3, cache: Path, examples_dir: Path, run_cli) -> None:
    config = lerobot_panda_config(examples_dir, "lerobot_s3_empty", {"lerobot": s3.url("nothing/here")})
    result = run_cli("validate", str(config))
    assert result.code == 1 and f"{s3.url('nothing/here')}/meta/info.json is missing" in result.err, result.err


def test_a_local_dataset_hashes_as_before_remote_datasets(examples_dir: Path, allow_examples: Path) -> None:
    from urdf_pipeline.dataset.fingerprint import _canonical

    plan = load(examples_dir / "so101_dataset.yaml")
    source = plan.segments[0].sources[0]
    assert source.remote is None and "remote" not in _canonical(source), "a local plan's `remote` (None) is left out"


def test_check_reads_the_first_episode_from_its_view(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    write_dataset(tmp_path / "dataset", _episodes(examples_dir, seed=80), "v2.1")
    _upload(s3, "checked", tmp_path / "dataset")
    config = lerobot_panda_config(examples_dir, "lerobot_s3_check", {"lerobot": s3.url("checked")})
    result = run_cli("check", str(config))
    assert result.code == 0, result.err
    assert "panda_joint1 -> panda_joint1" in result.out
    assert cached_names(cache) == ["episode_000000.parquet", "episodes.jsonl", "info.json", "tasks.jsonl"], "episode 0's data only"


def test_the_python_api_reads_an_s3_episode_as_the_local_dataset_gives_it(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import rerun as rr

    from urdf_pipeline import forward_kinematics, log

    episodes = _episodes(examples_dir, seed=90)
    write_dataset(tmp_path / "dataset", episodes, "v3")
    _upload(s3, "api", tmp_path / "dataset")
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", f"{tmp_path}:{examples_dir}")
    config = lerobot_panda_config(examples_dir, "lerobot_s3_api", {"lerobot": s3.url("api")})
    remote = forward_kinematics(config, "episode_000001")
    local = forward_kinematics(
        lerobot_panda_config(examples_dir, "lerobot_local_api", {"lerobot": str(tmp_path / "dataset")}), "episode_000001"
    )
    assert remote["arm"].links == local["arm"].links and len(remote["arm"].times["frame_index"]) == LENGTHS[1]
    assert np.array_equal(remote["arm"].translations, local["arm"].translations)
    assert np.array_equal(remote["arm"].quaternions, local["arm"].quaternions)

    recording = rr.RecordingStream("my_app", recording_id="episode_000002")
    saved = tmp_path / "mine.rrd"
    recording.save(saved)
    assert log(config, recording, segment="episode_000002") == {"arm": LENGTHS[2]}
    recording.flush()
    recording.disconnect()
    q = episodes[2]
    assert_panda_fk(examples_dir, saved, "frame_index", list(range(len(q))), q, [0, len(q) - 1])

"""Parquet sources on S3 (a real S3 endpoint: moto_server on 127.0.0.1): `validate` and `plan` read the footer by
ranged GETs and download no data, `run` fetches each object once into the download cache and gives poses equal to
pinocchio's, a glob over a prefix makes a segment per object, a re-run reads nothing again, and an object that changed
after the plan was made is a clear error, never a mixed dataset."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline import load
from urdf_pipeline.dataset import RunOptions, run_dataset
from urdf_pipeline.examples import write_joint_parquet

from ..conftest import S3
from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, random_panda_q
from .conftest import cached_files

FRAMES = 120


def _upload_episode(s3: S3, key: str, q: np.ndarray, folder: Path) -> None:
    local = folder / key.replace("/", "_")
    write_joint_parquet(local, q)
    s3.client().upload_file(str(local), s3.bucket, key)


def _source(url: str) -> dict[str, object]:
    return {"parquet": url, "column": "observation.state", "index": "frame_index", "names": PANDA_JOINTS}


def test_a_parquet_file_on_s3_is_planned_from_its_footer_and_run_from_the_cache(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli
) -> None:
    q = random_panda_q(examples_dir, FRAMES, seed=11)
    _upload_episode(s3, "runs/episode_a.parquet", q, tmp_path)
    config = panda_config(examples_dir, "s3_single", _source(s3.url("runs/episode_a.parquet")))

    for command in ("validate", "plan"):
        result = run_cli(command, str(config))
        assert result.code == 0, result.err
    assert cached_files(cache) == [], "validate and plan read the footer only: nothing downloaded"
    footers = [p for p in cache.rglob("*.footer")]
    assert len(footers) == 1 and footers[0].stat().st_size < 10_000, "the footer alone, kept for the next command"
    assert s3.url("runs/episode_a.parquet") in run_cli("plan", str(config), "--format", "json").out

    first = run_cli("run", str(config), "--force")
    assert first.code == 0, first.err
    recording = examples_dir / "out" / "sources" / "s3_single.rrd"
    assert_panda_fk(examples_dir, recording, "frame_index", list(range(FRAMES)), q, [0, 57, FRAMES - 1])
    cached = cached_files(cache)
    assert [p.name for p in cached] == ["episode_a.parquet"]
    manifest = json.loads((examples_dir / "out" / "sources" / "s3_single.manifest.json").read_text())
    entry = next(e for e in manifest["segments"] if e["segment"] == "s3_single")
    etag = s3.client().head_object(Bucket=s3.bucket, Key="runs/episode_a.parquet")["ETag"].strip('"')
    assert entry["inputs"] == {s3.url("runs/episode_a.parquet"): etag}, "the manifest records what the run read"

    again = run_cli("run", str(config))
    assert again.code == 0 and "up to date" in again.err, again.err
    assert cached_files(cache) == cached


def test_a_glob_over_a_prefix_is_a_segment_per_object(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    values = {stem: random_panda_q(examples_dir, FRAMES, seed=20 + n) for n, stem in enumerate(["ep_0", "ep_1", "ep_2"])}
    for stem, q in values.items():
        _upload_episode(s3, f"glob/{stem}.parquet", q, tmp_path)
    s3.client().put_object(Bucket=s3.bucket, Key="glob/notes.txt", Body=b"not matched")
    config = panda_config(examples_dir, "{stem}", _source(s3.url("glob/*.parquet")))
    result = run_cli("run", str(config), "--force", "--jobs", "1")
    assert result.code == 0, result.err
    for stem, q in values.items():
        assert_panda_fk(examples_dir, examples_dir / "out" / "sources" / f"{stem}.rrd", "frame_index", list(range(FRAMES)), q, [3])


def test_an_object_changed_after_planning_fails_its_segment_by_name(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    _upload_episode(s3, "changed/episode.parquet", random_panda_q(examples_dir, FRAMES, seed=1), tmp_path)
    config = panda_config(examples_dir, "s3_changed", _source(s3.url("changed/episode.parquet")))
    plan = load(config)
    _upload_episode(s3, "changed/episode.parquet", random_panda_q(examples_dir, FRAMES, seed=2), tmp_path / "later")
    finished = run_dataset(plan, RunOptions(1, "local", None, True))
    assert [r.status for r in finished.results] == ["failed"]
    reason = finished.results[0].reason
    assert "changed after it was planned" in reason and s3.url("changed/episode.parquet") in reason, reason
    assert cached_files(cache) == []  # the refused download left nothing that counts


def test_a_bucket_the_environment_does_not_allow_is_refused_before_any_request(
    s3: S3, examples_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    monkeypatch.setenv("AWS_ENDPOINT_URL", "http://127.0.0.1:9")  # nothing listens: any request would fail differently
    config = panda_config(examples_dir, "s3_refused", _source("s3://someone-elses-bucket/data.parquet"))
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "s3_refused.yaml:" in result.err and "sources.state.parquet" in result.err, result.err
    assert "is not under a location this run allows" in result.err and "URDF_PIPELINE_ALLOW_URLS=" in result.err


def test_a_repeated_index_in_a_remote_file_is_named_by_its_url(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    """The data checks run on the downloaded file, and their messages name the URL, not the download cache's path."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    q = random_panda_q(examples_dir, 10, seed=5)
    local = tmp_path / "repeats.parquet"
    column = pa.FixedSizeListArray.from_arrays(pa.array(q.astype(np.float32).reshape(-1)), 8)
    pq.write_table(pa.table({"frame_index": pa.array([0, 1, 2, 2, 4, 5, 6, 7, 8, 9], pa.int64()), "observation.state": column}), local)
    s3.client().upload_file(str(local), s3.bucket, "repeats/episode.parquet")
    config = panda_config(examples_dir, "s3_repeats", _source(s3.url("repeats/episode.parquet")))
    result = run_cli("run", str(config), "--force")
    assert result.code == 1
    assert s3.url("repeats/episode.parquet") in result.err and str(cache) not in result.err, result.err

"""CSV, MCAP, HDF5 and .rrd sources on S3 (a real S3 endpoint: moto_server on 127.0.0.1), as parquet's are
(test_sources_s3.py): `validate` and `plan` read metadata only by ranged GETs (a CSV's first block, an MCAP summary and
first message, an HDF5 file's structure) and download nothing, but an .rrd, which Rerun's reader opens from a local
path only, is downloaded once by `validate` into the cache that `run` reads it from. `run` gives poses equal to
pinocchio's; the data checks a local file gets at compile run once the file is downloaded."""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from urdf_pipeline import load
from urdf_pipeline.dataset import RunOptions, run_dataset
from urdf_pipeline.remote import open_range, parse_url
from urdf_pipeline.remote.s3_objects import head
from urdf_pipeline.sources import csv as csv_kind
from urdf_pipeline.sources import hdf5 as hdf5_kind
from urdf_pipeline.sources import mcap_remote

from ..conftest import S3
from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, random_panda_q
from .conftest import cached_files
from .test_sources_hdf5 import write_aloha_episode
from .test_sources_mcap import shuffled_messages, write_joint_states
from .test_sources_rrd import write_state_rrd
from .test_sources_wide import write_wide_csv

FRAMES = 120
KINDS = ("csv", "mcap", "hdf5", "rrd")


def _upload(s3: S3, local: Path, key: str) -> str:
    s3.client().upload_file(str(local), s3.bucket, key)
    return s3.url(key)


def _write(kind: str, folder: Path, q: np.ndarray, seed: int) -> tuple[Path, dict[str, Any], str, list[int]]:
    """A local file of `kind` holding `q`, the source entry (its path key left to fill), the timeline and its times."""
    folder.mkdir(parents=True, exist_ok=True)
    frames = list(range(len(q)))
    if kind == "csv":
        path = folder / "episode.csv"
        write_wide_csv(path, {"frame": np.arange(len(q)), **{name: q[:, i] for i, name in enumerate(PANDA_JOINTS)}})
        return path, {"index": "frame"}, "frame", frames
    if kind == "mcap":
        path = folder / "episode.mcap"
        stamps = write_joint_states(path, shuffled_messages(q, seed=seed), chunk_size=2048)  # several chunks
        return path, {"topic": "/joint_states"}, "ros2_timestamp", stamps  # no names: the first message's
    if kind == "hdf5":
        path = folder / "episode.hdf5"
        write_aloha_episode(path, q, time_s=np.arange(len(q)) / 50.0)
        return (
            path,
            {"dataset": "/observations/qpos", "names": PANDA_JOINTS, "index": "/observations/frame"},
            "frame",
            [2 * f for f in frames],
        )
    path = folder / "episode.rrd"
    write_state_rrd(path, q, PANDA_JOINTS)
    return path, {"entity": "/observation.state"}, "frame_index", frames


@pytest.mark.parametrize("kind", KINDS)
def test_a_file_on_s3_is_planned_from_its_metadata_and_run_from_the_cache(
    kind: str, s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(csv_kind, "CSV_BLOCK_BYTES", 4096)  # the CSV spans blocks: its first one ends inside a line
    q = random_panda_q(examples_dir, FRAMES, seed=31 + KINDS.index(kind))
    local, entry, timeline, times = _write(kind, tmp_path / "local", q, seed=41)
    url = _upload(s3, local, f"runs/{local.name}")
    config = panda_config(examples_dir, f"s3_{kind}", {kind: url, **entry})

    for command in ("validate", "plan"):
        result = run_cli(command, str(config))
        assert result.code == 0, result.err
    planned = cached_files(cache)
    if kind == "rrd":  # Rerun's reader opens local files only: validate downloaded it, into the cache run reads
        assert [p.name for p in planned] == [local.name] and planned[0].read_bytes() == local.read_bytes()
        downloaded = planned[0].stat().st_ino, planned[0].stat().st_mtime_ns
    else:
        assert planned == [], "validate and plan read metadata only: nothing downloaded"
    assert url in run_cli("plan", str(config), "--format", "json").out

    first = run_cli("run", str(config), "--force")
    assert first.code == 0, first.err
    recording = examples_dir / "out" / "sources" / f"s3_{kind}.rrd"
    assert_panda_fk(examples_dir, recording, timeline, times, q, [0, 57, FRAMES - 1])
    cached = cached_files(cache)
    assert [p.name for p in cached] == [local.name]
    if kind == "rrd":
        assert (cached[0].stat().st_ino, cached[0].stat().st_mtime_ns) == downloaded, "run read validate's download"

    again = run_cli("run", str(config))
    assert again.code == 0 and "up to date" in again.err, again.err
    assert cached_files(cache) == cached


def test_a_glob_over_a_prefix_is_a_segment_per_object(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    values = {stem: random_panda_q(examples_dir, FRAMES, seed=60 + n) for n, stem in enumerate(["take_0", "take_1", "take_2"])}
    for stem, q in values.items():
        local = tmp_path / f"{stem}.hdf5"
        write_aloha_episode(local, q)
        _upload(s3, local, f"takes/{stem}.hdf5")
    s3.client().put_object(Bucket=s3.bucket, Key="takes/README.md", Body=b"not matched")
    source = {"hdf5": s3.url("takes/*.hdf5"), "dataset": "/observations/qpos", "names": PANDA_JOINTS}
    config = panda_config(examples_dir, "{stem}", source)
    assert run_cli("validate", str(config)).code == 0 and cached_files(cache) == []
    result = run_cli("run", str(config), "--force", "--jobs", "1")
    assert result.code == 0, result.err
    for stem, q in values.items():
        assert_panda_fk(examples_dir, examples_dir / "out" / "sources" / f"{stem}.rrd", "row_index", list(range(FRAMES)), q, [3])
    assert sorted(p.name for p in cached_files(cache)) == [f"{stem}.hdf5" for stem in values]


def test_plan_and_diff_show_the_url(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    """A source moved from a local file to the same file on S3: the report shows the URL, diff the path's change only."""
    local, entry, _, _ = _write("hdf5", examples_dir / "data" / "to_s3", random_panda_q(examples_dir, FRAMES, seed=12), seed=13)
    url = _upload(s3, local, "moved/episode.hdf5")
    before = panda_config(examples_dir, "s3_moved_before", {"hdf5": "data/to_s3/episode.hdf5", **entry})
    after = panda_config(examples_dir, "s3_moved_after", {"hdf5": url, **entry})
    report = run_cli("plan", str(after), "--format", "markdown")
    assert report.code == 0 and url in report.out and str(cache) not in report.out, report.out
    changed = run_cli("diff", str(before), str(after))
    assert changed.code == 0, changed.err
    lines = [line for line in changed.out.splitlines() if "source state" in line]
    assert len(lines) == 1 and "data/to_s3/episode.hdf5" in lines[0] and url in lines[0], changed.out
    assert "RemoteObject" not in changed.out and cached_files(cache) == []


def test_an_object_changed_after_planning_fails_its_segment_by_name(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    local, entry, _, _ = _write("mcap", tmp_path / "first", random_panda_q(examples_dir, FRAMES, seed=1), seed=2)
    url = _upload(s3, local, "changed/episode.mcap")
    plan = load(panda_config(examples_dir, "s3_mcap_changed", {"mcap": url, **entry}))
    later, _, _, _ = _write("mcap", tmp_path / "later", random_panda_q(examples_dir, FRAMES, seed=3), seed=4)
    _upload(s3, later, "changed/episode.mcap")
    finished = run_dataset(plan, RunOptions(1, "local", None, True))
    assert [r.status for r in finished.results] == ["failed"]
    reason = finished.results[0].reason
    assert "changed after it was planned" in reason and url in reason, reason
    assert cached_files(cache) == []  # the refused download left nothing that counts


def test_hdf5_values_are_checked_once_run_has_downloaded_the_file(s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    """A local file's index values are checked by validate; a remote file's, after run's download (the same check)."""
    q = random_panda_q(examples_dir, FRAMES, seed=5)
    local = tmp_path / "late.hdf5"
    write_aloha_episode(local, q, time_s=np.arange(FRAMES) / 50.0)
    with h5py.File(local, "r+") as file:
        file["/observations/time"][FRAMES - 1] = 1e11  # seconds: beyond what int64 nanoseconds hold (year 2262)
    url = _upload(s3, local, "late/late.hdf5")
    source = {
        "hdf5": url,
        "dataset": "/observations/qpos",
        "names": PANDA_JOINTS,
        "index": {"timestamp": "/observations/time", "unit": "s"},
    }
    config = panda_config(examples_dir, "s3_hdf5_late", source)
    assert run_cli("validate", str(config)).code == 0 and cached_files(cache) == []
    result = run_cli("run", str(config), "--force")
    assert result.code == 1
    assert "s3_hdf5_late.yaml:" in result.err and "index dataset '/observations/time'" in result.err, result.err
    assert "beyond a timeline's range" in result.err, result.err
    assert not (examples_dir / "out" / "sources" / "s3_hdf5_late.rrd").exists()


def test_metadata_reads_take_a_few_ranged_requests(s3: S3, examples_dir: Path, tmp_path: Path) -> None:
    """The request counts behind "metadata only": an MCAP summary in 3 (the magic, the footer, the summary), its first
    message's chunk in 1 more; an
    ALOHA-style HDF5 file's structure (camera images beside the joints) within a few, far from the file's size."""
    q = random_panda_q(examples_dir, FRAMES, seed=7)
    local, _, _, _ = _write("mcap", tmp_path, q, seed=8)
    remote = head(parse_url(_upload(s3, local, "count/episode.mcap")), None)
    with mcap_remote.remote_mcap(remote, None) as file:
        info = file.info()
        summary_requests = file.stream.raw.requests
        names = file.first_names(["/joint_states"])
        first_message_requests = file.stream.raw.requests - summary_requests
    assert {c.topic for c in info.channels} == {"/joint_states", "/chatter"}
    assert [c.message_count for c in info.channels if c.topic == "/joint_states"] == [FRAMES]
    assert names is not None and sorted(names) == sorted(PANDA_JOINTS)
    assert names == tuple(shuffled_messages(q, seed=8)[0][0])  # the first message's own order
    assert summary_requests <= 3 and first_message_requests <= 1, (summary_requests, first_message_requests)

    images = tmp_path / "aloha.hdf5"
    with h5py.File(images, "w") as file:  # joints beside 40 MB of camera images, as ALOHA records them
        file.create_dataset("/observations/qpos", data=q)
        file.create_dataset("/observations/images/cam_high", data=np.full((FRAMES, 240, 480, 3), 7, np.uint8))
        file.create_dataset("/observations/time", data=np.arange(FRAMES) / 50.0)
    remote = head(parse_url(_upload(s3, images, "count/aloha.hdf5")), None)
    with open_range(remote, None, block=hdf5_kind.REMOTE_BLOCK, max_requests=hdf5_kind.REMOTE_REQUESTS) as reader:
        with h5py.File(reader, "r") as file:
            named = hdf5_kind._Named(remote.url, "aloha.hdf5", remote.size)
            assert hdf5_kind._node(file, "/observations/qpos", named, None).shape == (FRAMES, 8)
        requests, fetched = reader.raw.requests, reader.raw.fetched
    assert requests <= 4 and fetched <= 4 * hdf5_kind.REMOTE_BLOCK and fetched * 40 < remote.size, (requests, fetched, remote.size)


def test_an_hdf5_file_whose_structure_is_spread_wide_is_downloaded_by_validate(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past REMOTE_REQUESTS ranged GETs (a file of many chunks or groups), h5py reads a downloaded copy instead."""
    monkeypatch.setattr(hdf5_kind, "REMOTE_REQUESTS", 1)
    q = random_panda_q(examples_dir, FRAMES, seed=9)
    local = tmp_path / "wide.hdf5"
    write_aloha_episode(local, q)
    url = _upload(s3, local, "spread/wide.hdf5")
    config = panda_config(examples_dir, "s3_hdf5_spread", {"hdf5": url, "dataset": "/observations/qpos", "names": PANDA_JOINTS})
    assert run_cli("validate", str(config)).code == 0
    assert [p.name for p in cached_files(cache)] == ["wide.hdf5"]
    result = run_cli("run", str(config), "--force")
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, examples_dir / "out" / "sources" / "s3_hdf5_spread.rrd", "row_index", list(range(FRAMES)), q, [0, 99])


def _without_summary(path: Path) -> bytes:
    """The MCAP file as a recorder killed before its end leaves it once `mcap recover`-ed without an index: the data
    section, then a footer whose summary_start is 0."""
    data = path.read_bytes()
    magic = b"\x89MCAP0\r\n"
    footer_start = len(data) - len(magic) - 1 - 8 - 20
    assert data[footer_start] == 0x02  # the footer's opcode
    summary_start = struct.unpack_from("<Q", data, footer_start + 9)[0]
    return data[:summary_start] + bytes([0x02]) + struct.pack("<QQQI", 20, 0, 0, 0) + magic


def test_mcap_refusals_name_the_url(
    s3: S3, cache: Path, examples_dir: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    local, entry, _, _ = _write("mcap", tmp_path, random_panda_q(examples_dir, FRAMES, seed=10), seed=11)
    s3.client().put_object(Bucket=s3.bucket, Key="bad/unindexed.mcap", Body=_without_summary(local))
    config = panda_config(examples_dir, "s3_mcap_unindexed", {"mcap": s3.url("bad/unindexed.mcap"), **entry})
    result = run_cli("validate", str(config))
    assert result.code == 1 and "sources.state.mcap" in result.err and s3.url("bad/unindexed.mcap") in result.err
    assert "has no summary section" in result.err, result.err

    url = _upload(s3, local, "bad/big_chunks.mcap")
    monkeypatch.setattr(mcap_remote, "METADATA_BLOCK", 512)
    with mcap_remote.remote_mcap(head(parse_url(url), None), None) as file:
        summary_bytes = file.stream.raw.fetched
    monkeypatch.setattr(mcap_remote, "METADATA_BYTES", summary_bytes + 512)  # the summary fits, the first chunk does not
    result = run_cli("validate", str(panda_config(examples_dir, "s3_mcap_budget", {"mcap": url, **entry})))
    assert result.code == 1 and url in result.err and "give the names with names: [...]" in result.err, result.err
    named = run_cli("validate", str(panda_config(examples_dir, "s3_mcap_named", {"mcap": url, **entry, "names": PANDA_JOINTS})))
    assert named.code == 0, named.err  # with names, the summary alone is read
    assert cached_files(cache) == []


def test_csv_refusals_name_the_url(s3: S3, cache: Path, examples_dir: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(csv_kind, "CSV_BLOCK_BYTES", 64)
    s3.client().put_object(Bucket=s3.bucket, Key="bad/long_header.csv", Body=("frame," + ",".join(["x" * 20] * 8) + "\n0,1\n").encode())
    config = panda_config(examples_dir, "s3_csv_long_header", {"csv": s3.url("bad/long_header.csv"), "index": "frame"})
    result = run_cli("validate", str(config))
    assert result.code == 1 and s3.url("bad/long_header.csv") in result.err and "longer than 64 bytes" in result.err, result.err
    missing = run_cli("validate", str(panda_config(examples_dir, "s3_csv_missing", {"csv": s3.url("bad/none.csv"), "index": "frame"})))
    assert missing.code == 1 and "sources.state.csv" in missing.err
    assert f"cannot read {s3.url('bad/none.csv')}: no such object (404)" in missing.err, missing.err
    assert cached_files(cache) == []


@pytest.mark.parametrize("kind", KINDS)
def test_a_bucket_the_environment_does_not_allow_is_refused_before_any_request(
    kind: str, s3: S3, examples_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    monkeypatch.setenv("AWS_ENDPOINT_URL", "http://127.0.0.1:9")  # nothing listens: any request would fail differently
    entry = {"csv": {"index": "frame"}, "mcap": {"topic": "/joint_states"}, "hdf5": {"dataset": "/q"}, "rrd": {"entity": "/q"}}[kind]
    config = panda_config(examples_dir, f"s3_refused_{kind}", {kind: f"s3://someone-elses-bucket/data/*.{kind}", **entry})
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert f"sources.state.{kind}" in result.err and "is not under a location this run allows" in result.err, result.err
    assert os.environ["AWS_ENDPOINT_URL"] not in result.err

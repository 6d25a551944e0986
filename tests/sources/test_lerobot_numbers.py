"""Every number a LeRobot dataset's metadata declares is checked where it is read: info.json's counts, fps and shapes,
the episodes' table (v2 episodes.jsonl, v3 meta/episodes parquet), the episodes listed from total_episodes alone. Each
hostile dataset is built here, in tmp_path, from the writers the tests share (tests/lerobot_layouts.py), and each
refusal is a user error naming the file and the key; through the command line, exit 1 without a traceback in
validate, plan, run and init, for local, S3 and Hub datasets."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.examples import write_lerobot_dataset
from urdf_pipeline.sources import lerobot_numbers
from urdf_pipeline.sources.lerobot_meta import episode_lengths, episode_table, metadata, read_info

from ..conftest import S3
from ..lerobot_layouts import HOSTILE_LEROBOT, dataset_files, hub_commit, lerobot_panda_config, write_hostile_lerobot, write_v3_dataset

NAMES = ["a", "b"]
HUGE = 10**30


def _v2(root: Path, episodes: int = 3) -> Path:
    write_lerobot_dataset(root, [np.zeros((4, 2)) + n for n in range(episodes)], NAMES)
    return root


def _v3(root: Path) -> Path:
    write_v3_dataset(root, [np.zeros((4, 2)) + n for n in range(4)], NAMES)
    return root


def _info(root: Path, **changes: Any) -> None:
    path = root / "meta" / "info.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))  # NaN and Infinity as Python writes them


def _refused_info(root: Path, *expected: str) -> None:
    with pytest.raises(UserError) as refused:
        read_info(root)
    for text in expected:
        assert text in refused.value.message, refused.value.message
    assert str(root / "meta" / "info.json") in refused.value.message


@pytest.mark.parametrize("value", [0, -1, HUGE, float("nan"), float("inf"), "1000", True, 1.5, None, [1000]])
def test_chunks_size_must_be_a_whole_number_from_one(value: object, tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    _info(root, chunks_size=value)
    _refused_info(root, "chunks_size in", "must be a whole number from 1 to 9,223,372,036,854,775,807")


@pytest.mark.parametrize("key", sorted(set(lerobot_numbers.INFO_COUNTS) - {"chunks_size"}))
@pytest.mark.parametrize("value", [-1, HUGE, float("nan"), "3", False])
def test_every_count_of_info_json_is_a_whole_number(key: str, value: object, tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    _info(root, **{key: value})
    _refused_info(root, f"{key} in", "must be a whole number from 0")


@pytest.mark.parametrize("fps", [0, -30, float("nan"), float("inf"), float("-inf"), 10**7, "30", True])
def test_fps_is_a_positive_bounded_number(fps: object, tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    _info(root, fps=fps)
    _refused_info(root, "fps in", "must be a number above 0 and at most 1,000,000")


@pytest.mark.parametrize("shape", [[-2], [HUGE], [2.0], "2", 2])
def test_a_feature_shape_is_a_list_of_sizes(shape: object, tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    info = json.loads((root / "meta" / "info.json").read_text())
    info["features"]["observation.state"]["shape"] = shape
    (root / "meta" / "info.json").write_text(json.dumps(info))
    _refused_info(root, "features.observation.state.shape in")


def test_accepted_numbers_are_read_as_they_are(tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    _info(root, fps=29.97, chunks_size=2**63 - 1, total_frames=0)
    assert read_info(root)["fps"] == 29.97


def test_info_json_is_read_within_its_bound(tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    (root / "meta" / "info.json").write_text(json.dumps({"pad": "x" * (4 * 2**20)}))
    _refused_info(root, "larger than 4 MB")
    (root / "meta" / "info.json").write_text("[" * 100_000 + "]" * 100_000)
    _refused_info(root, "nested too deeply")


def _episodes_refused(root: Path, *expected: str) -> None:
    with pytest.raises(UserError) as refused:
        metadata(str(root), None, lambda: episode_lengths(root, episode_table(root), None, str(root)))
    for text in expected:
        assert text in refused.value.message, refused.value.message


@pytest.mark.parametrize(
    ("line", "says"),
    [
        ({"episode_index": "1"}, "episode_index in meta/episodes.jsonl line 2 is '1'"),
        ({"episode_index": True}, "episode_index in meta/episodes.jsonl line 2 is true"),
        ({"episode_index": -1}, "episode_index in meta/episodes.jsonl line 2 is -1"),
        ({"episode_index": 1e30}, "episode_index in meta/episodes.jsonl line 2 is 1e+30"),
        ({"episode_index": HUGE}, "episode_index in meta/episodes.jsonl line 2 is 1000000000000000000000000000000"),
        ({"episode_index": float("nan")}, "episode_index in meta/episodes.jsonl line 2 is NaN"),
        ({"length": -4}, "length in meta/episodes.jsonl line 2 is -4"),
        ({"length": 4.5}, "length in meta/episodes.jsonl line 2 is 4.5"),
    ],
)
def test_v2_episode_lines_hold_whole_numbers(line: dict[str, Any], says: str, tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    path = root / "meta" / "episodes.jsonl"
    rows = [json.loads(text) for text in path.read_text().splitlines()]
    rows[1].update(line)
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    _episodes_refused(root, "LeRobot dataset", says, "whole number from 0")


def test_v2_episodes_jsonl_is_read_within_its_bound(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = _v2(tmp_path / "ds")
    monkeypatch.setattr(lerobot_numbers, "EPISODES_JSONL_BYTES", 100)  # the bound as 100 bytes: 3 lines pass it
    _episodes_refused(root, "meta/episodes.jsonl is larger than")


def _episodes_file(root: Path, column: str, values: list[Any], kind: pa.DataType | None = None) -> None:
    path = root / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
    table = pq.read_table(path)
    array = pa.array(values, kind)
    if column in table.column_names:
        table = table.set_column(table.column_names.index(column), column, array)
    else:
        table = table.append_column(column, array)
    pq.write_table(table, path)


@pytest.mark.parametrize(
    ("column", "values", "kind", "says"),
    [
        ("data/chunk_index", [0, 0, -1, 0], None, "data/chunk_index in meta/episodes/chunk-000/file-000.parquet is -1 at row 2"),
        (
            "data/file_index",
            [0, 0, 1, 2**64 - 1],
            pa.uint64(),
            "data/file_index in meta/episodes/chunk-000/file-000.parquet is 18446744073709551615 at row 3",
        ),
        ("data/chunk_index", [0, 0, 0, 0], pa.uint8(), None),
        (
            "data/file_index",
            [0.0, 0.0, 1.0, 1.0],
            None,
            "data/file_index in meta/episodes/chunk-000/file-000.parquet holds double, not whole numbers",
        ),
        ("episode_index", [0, None, 2, 3], pa.int64(), "episode_index in meta/episodes/chunk-000/file-000.parquet is null at row 1"),
        ("length", [4, -4, 4, 4], None, "length in meta/episodes/chunk-000/file-000.parquet is -4 at row 1"),
        ("dataset_from_index", [0, -4, 8, 12], None, "dataset_from_index in meta/episodes/chunk-000/file-000.parquet is -4 at row 1"),
        (
            "dataset_to_index",
            [4, 8, 0, 16],
            None,
            "dataset_to_index in meta/episodes/chunk-000/file-000.parquet is 0 at row 2: it must be not before dataset_from_index",
        ),
        (
            "videos/cam/from_timestamp",
            [0.0, float("nan"), 0.0, 0.0],
            None,
            "videos/cam/from_timestamp in meta/episodes/chunk-000/file-000.parquet is NaN at row 1",
        ),
        (
            "videos/cam/to_timestamp",
            [1.0, 1.0, -1.0, 1.0],
            None,
            "videos/cam/to_timestamp in meta/episodes/chunk-000/file-000.parquet is -1.0 at row 2",
        ),
        (
            "videos/cam/chunk_index",
            [0, 0, 0, -3],
            None,
            "videos/cam/chunk_index in meta/episodes/chunk-000/file-000.parquet is -3 at row 3",
        ),
    ],
)
def test_v3_episode_columns_hold_their_numbers(
    column: str, values: list[Any], kind: pa.DataType | None, says: str | None, tmp_path: Path
) -> None:
    root = _v3(tmp_path / "ds")
    _episodes_file(root, column, values, kind)
    if says is None:  # accepted as written
        assert list(episode_lengths(root, episode_table(root), None, str(root))) == [0, 1, 2, 3]
        return
    _episodes_refused(root, says)


def test_v3_video_ranges_end_after_they_start(tmp_path: Path) -> None:
    root = _v3(tmp_path / "ds")
    _episodes_file(root, "videos/cam/from_timestamp", [0.0, 2.0, 0.0, 0.0])
    _episodes_file(root, "videos/cam/to_timestamp", [1.0, 1.0, 1.0, 1.0])
    _episodes_refused(
        root,
        "videos/cam/to_timestamp in meta/episodes/chunk-000/file-000.parquet is 1.0 at row 1: it must be not before videos/cam/from_timestamp",
    )


def test_episodes_listed_from_total_episodes_alone_are_bounded(tmp_path: Path) -> None:
    root = _v2(tmp_path / "ds")
    (root / "meta" / "episodes.jsonl").unlink()
    _info(root, total_episodes=3)
    assert list(episode_lengths(root, None, None, str(root))) == [0, 1, 2]
    _info(root, total_episodes=lerobot_numbers.MAX_LISTED_EPISODES + 1)
    with pytest.raises(UserError, match="at most 1,000,000 episodes are taken from total_episodes alone"):
        episode_lengths(root, None, None, str(root))


# Through the command line: every command that reads a dataset's metadata refuses each hostile dataset with exit 1


@pytest.mark.parametrize("name", sorted(HOSTILE_LEROBOT))
def test_hostile_metadata_is_refused_by_every_command(
    name: str, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(tmp_path))
    write_hostile_lerobot(tmp_path / "data", examples_dir / "data" / "so101_lerobot")
    dataset = tmp_path / "data" / "hostile_lerobot" / name
    config = examples_dir / f"hostile_lerobot_{name}.yaml"
    text = (examples_dir / "so101_dataset.yaml").read_text()
    assert "lerobot: data/so101_lerobot" in text
    config.write_text(text.replace("lerobot: data/so101_lerobot", f"lerobot: {dataset}"))
    for command in ("validate", "plan", "run"):
        result = run_cli(command, str(config))
        _assert_one_located_error(result, command, str(config))
    urdf = examples_dir / "robots" / "share" / "example-robot-data" / "robots" / "so_arm_description" / "urdf" / "so101.urdf"
    result = run_cli("init", "--urdf", str(urdf), "--source", f"lerobot:{dataset}", "-o", str(tmp_path / "init.yaml"))
    if result.code != 0:  # init reads info.json and the feature's names; a hostile episodes table is run's to find
        _assert_one_located_error(result, "init", "")


def _assert_one_located_error(result: Any, command: str, config: str) -> None:
    assert result.code == 1, f"{command}: exit {result.code}\n{result.err}"
    assert "Traceback" not in result.err and "internal error" not in result.err, result.err
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    assert errors and all(line.startswith(f"error: {config}") for line in errors), result.err


def test_hostile_metadata_on_s3_and_the_hub_is_named_by_its_url(
    s3: S3, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(tmp_path / "download-cache"))
    write_hostile_lerobot(tmp_path / "data", examples_dir / "data" / "so101_lerobot")
    for name, says in (("chunks_size_zero", "chunks_size in"), ("data_path_width", "writes '{episode_index:999999999d}'")):
        dataset = tmp_path / "data" / "hostile_lerobot" / name
        for relative in dataset_files(dataset):
            s3.client().upload_file(str(dataset / relative), s3.bucket, f"hostile/{name}/{relative}")
        config = lerobot_panda_config(examples_dir, f"lerobot_s3_{name}", {"lerobot": s3.url(f"hostile/{name}")})
        result = run_cli("validate", str(config))
        assert result.code == 1 and says in result.err and s3.url(f"hostile/{name}/meta/info.json") in result.err, result.err
    pytest.importorskip("huggingface_hub", reason="the hub extra: pip install 'urdf-pipeline[hub]'")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hub-cache"))
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf-home"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_URLS", "hf://datasets/robots/")
    sha = "1" * 40
    hub_commit(tmp_path / "hub-cache", "robots/hostile", tmp_path / "data" / "hostile_lerobot" / "episode_index_huge", sha)
    config = lerobot_panda_config(examples_dir, "lerobot_hub_hostile", {"lerobot": f"hf://datasets/robots/hostile@{sha}"})
    result = run_cli("validate", str(config))
    assert result.code == 1 and "episode_index in meta/episodes.jsonl line 2 is 1e+30" in result.err, result.err
    assert "hf://datasets/robots/hostile" in result.err and "Traceback" not in result.err


@pytest.mark.parametrize(
    ("changes", "says"),
    [
        ({"total_chunks": 0}, "episode 2 is in chunk 0 (1,000 episodes a chunk) but total_chunks in"),
        ({"total_episodes": 2}, "meta/episodes lists episode 2 but total_episodes in"),
        ({"chunks_size": 1, "total_chunks": 2}, "episode 2 is in chunk 2 (1 episodes a chunk) but total_chunks in"),
    ],
)
def test_v2_episodes_agree_with_the_counts_rerun_reads_them_by(changes: dict[str, int], says: str, tmp_path: Path) -> None:
    """Rerun's v2 reader refuses an episode at or beyond total_episodes, or in a chunk at or beyond total_chunks: that
    would have been an exception inside the reader at run (exit 70), so compile refuses it."""
    root = _v2(tmp_path / "ds")
    _info(root, **changes)
    _episodes_refused(root, says, "the two must agree")


def test_a_v3_episodes_file_declaring_more_rows_than_the_bound_is_refused_before_it_is_read(tmp_path: Path) -> None:
    """An episodes file of a few hundred KB can declare millions of rows of zeros (30 million took 4 GB and 92 s
    before): its footer's rows count towards the bound, checked before any column is read."""
    root = _v3(tmp_path / "ds")
    rows = lerobot_numbers.MAX_EPISODE_ROWS + 1
    zeros = pa.array(np.zeros(rows, np.int64))
    path = root / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
    pq.write_table(pa.table({"episode_index": zeros, "length": zeros, "data/chunk_index": zeros, "data/file_index": zeros}), path)
    assert path.stat().st_size < 2**20
    _episodes_refused(root, "meta/episodes/chunk-000/file-000.parquet declares 1,000,001 rows", "beyond 1,000,000 rows")


@pytest.mark.parametrize(("column", "values"), [("episode_index", ["0", "1", "2", "3"]), ("length", [[1], [2], [3], [4]])])
def test_a_v3_column_of_another_type_is_refused_before_it_is_read(column: str, values: list[Any], tmp_path: Path) -> None:
    root = _v3(tmp_path / "ds")
    _episodes_file(root, column, values)
    _episodes_refused(root, f"{column} in meta/episodes/chunk-000/file-000.parquet holds", "not whole numbers")

"""A LeRobot v3 dataset keeps several episodes per data file: an episode's content hash covers the file(s) its rows
are in, found through meta/episodes (not every data file)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pyarrow as pa
import pyarrow.parquet as pq

from urdf_pipeline.errors import Where
from urdf_pipeline.sources.lerobot import episode_inputs


def test_a_v3_episode_is_read_from_the_data_file_the_episode_table_names(tmp_path: Path) -> None:
    (tmp_path / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    info = {"codebase_version": "v3.0", "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"}
    (tmp_path / "meta" / "info.json").write_text(json.dumps(info))
    episodes = pa.table({"episode_index": [0, 1, 2], "length": [5, 5, 5], "data/chunk_index": [0, 0, 0], "data/file_index": [0, 0, 1]})
    pq.write_table(episodes, tmp_path / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    for index in (0, 1):
        (tmp_path / "data" / "chunk-000").mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table({"episode_index": [index]}), tmp_path / "data" / "chunk-000" / f"file-{index:03d}.parquet")
    plan = SimpleNamespace(root=tmp_path, episode=2, remote=None, where=Where(tmp_path / "c.yaml", 0))  # a config beside the dataset
    assert episode_inputs(plan) == (tmp_path / "meta" / "info.json", tmp_path / "data" / "chunk-000" / "file-001.parquet")  # type: ignore[arg-type]
    plan = SimpleNamespace(root=tmp_path, episode=0, remote=None, where=Where(tmp_path / "c.yaml", 0))  # a config beside the dataset
    assert episode_inputs(plan)[1:] == (tmp_path / "data" / "chunk-000" / "file-000.parquet",)  # type: ignore[arg-type]


def test_a_data_file_the_metadata_names_must_be_there(tmp_path: Path) -> None:
    """v2 (a file per episode, where data_path says) and v3 (the file the episode table names): a missing one is a
    located error naming the episode and the file, in validate, not every data file read as the episode's (10,000
    episodes made that quadratic) nor a run that can only fail."""
    import numpy as np
    import pytest

    from urdf_pipeline.errors import UserError
    from urdf_pipeline.examples import write_lerobot_dataset

    write_lerobot_dataset(tmp_path / "v2", [np.zeros((5, 2)) for _ in range(3)], ["a", "b"])
    (tmp_path / "v2" / "data" / "chunk-000" / "episode_000001.parquet").unlink()
    plan = SimpleNamespace(root=tmp_path / "v2", episode=1, remote=None, where=Where(tmp_path / "c.yaml", 0))
    with pytest.raises(UserError, match=r"episode 1: its data file .*episode_000001\.parquet is missing"):
        episode_inputs(plan)  # type: ignore[arg-type]
    plan = SimpleNamespace(root=tmp_path / "v2", episode=2, remote=None, where=Where(tmp_path / "c.yaml", 0))
    assert episode_inputs(plan)[1:] == (tmp_path / "v2" / "data" / "chunk-000" / "episode_000002.parquet",)  # type: ignore[arg-type]

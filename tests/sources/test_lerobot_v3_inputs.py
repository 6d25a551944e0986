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

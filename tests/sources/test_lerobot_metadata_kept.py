"""A LeRobot dataset's metadata is read once per process while its files are unchanged (each segment of a run asks
for it: reading it each time made a 10,000-episode run quadratic), and read again as soon as a file changes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from urdf_pipeline.errors import Where
from urdf_pipeline.examples import write_lerobot_dataset
from urdf_pipeline.plan import LeRobotSourcePlan
from urdf_pipeline.sources import lerobot, lerobot_meta


def _plan(root: Path, episode: int) -> LeRobotSourcePlan:
    return LeRobotSourcePlan("state", root, "observation.state", episode, ("a", "b"), Where(root / "c.yaml", 0), per_segment=True)


def test_the_episode_lengths_are_kept_while_the_metadata_is_unchanged_and_read_again_when_it_changes(tmp_path: Path) -> None:
    write_lerobot_dataset(tmp_path, [np.zeros((5, 2)), np.zeros((7, 2))], ["a", "b"])
    plan = _plan(tmp_path, 0)
    assert lerobot.episodes(plan) == {0: 5, 1: 7}
    first = lerobot_meta.episode_table(tmp_path)
    assert lerobot_meta.episode_table(tmp_path) is first  # parsed once while the file is unchanged
    lerobot.episodes(plan)[0] = 99  # the caller's copy, not the one kept
    assert lerobot.episodes(plan) == {0: 5, 1: 7}

    jsonl = tmp_path / "meta" / "episodes.jsonl"
    jsonl.write_text(jsonl.read_text() + json.dumps({"episode_index": 2, "tasks": ["wave"], "length": 3}) + "\n")
    info = tmp_path / "meta" / "info.json"  # the count Rerun's reader reads episodes by, as LeRobot updates it too
    info.write_text(json.dumps({**json.loads(info.read_text()), "total_episodes": 3}))
    assert lerobot.episodes(plan) == {0: 5, 1: 7, 2: 3}


def _first_values(plan: LeRobotSourcePlan) -> tuple[int, float]:
    """(rows, the first joint value) of the episode's stream."""
    batches = [chunk.to_record_batch() for chunk in lerobot.open_stream(plan).stream]
    values = [batch.column(lerobot.VECTOR_COMPONENT).to_pylist() for batch in batches]
    return sum(len(v) for v in values), values[0][0][0][0]


def test_rerun_s_reader_is_opened_once_per_dataset_and_streams_each_episode(tmp_path: Path) -> None:
    write_lerobot_dataset(tmp_path, [np.full((5, 2), float(e)) for e in range(3)], ["a", "b"])
    assert [_first_values(_plan(tmp_path, e)) for e in (2, 0, 2)] == [(5, 2.0), (5, 0.0), (5, 2.0)]
    metadata = tuple(lerobot.stamped(tmp_path / "meta" / name) for name in ("info.json", "episodes.jsonl"))
    reader, known = lerobot._reader(tmp_path, metadata)
    assert known == {0, 1, 2}
    hits = lerobot._reader.cache_info().hits
    _first_values(_plan(tmp_path, 1))
    assert lerobot._reader.cache_info().hits == hits + 1, "the reader of the unchanged dataset is used again"
    assert lerobot._reader(tmp_path, metadata)[0] is reader

"""The manifest's segment summaries as a dataset browser reads them (`dataset.segment_summaries`): written by a
multi-segment run, equal to the sources read here with pyarrow and numpy, and read from hand-edited or old
manifests without an exception."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest

from urdf_pipeline.compile import compile_config
from urdf_pipeline.dataset import SegmentEntry, segment_summaries
from urdf_pipeline.errors import UserError

from ..dataset_helpers import SO101_JOINTS, isolated_examples, status_lines
from ..execute.test_ranges_and_preview import assert_codes_match, reference_bands

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

EPISODES = 4


@pytest.fixture
def so101_written(examples_dir: Path, tmp_path: Path, run_cli) -> Path:
    config = isolated_examples(examples_dir, tmp_path / "run")
    result = run_cli("run", str(config), "--jobs", "2")
    assert result.code == 0, result.err
    return config


def _manifest_path(config: Path) -> Path:
    return config.parent / "out" / "so101_dataset" / "so101_dataset.manifest.json"


def _episode(config: Path, episode: int) -> tuple[np.ndarray, np.ndarray]:
    """frame_index and the joint values in radians (the config: unit deg), read with pyarrow."""
    table = pq.read_table(config.parent / "data" / "so101_lerobot" / "data" / "chunk-000" / f"episode_{episode:06d}.parquet")
    state = table.column("observation.state").combine_chunks().flatten().to_numpy().astype(np.float64)
    return table.column("frame_index").to_numpy(), np.radians(state.reshape(len(table), len(SO101_JOINTS)))


def _timestamps(config: Path, episode: int) -> np.ndarray:
    """The episode's timestamp column (seconds since its start), as float64, read with pyarrow."""
    table = pq.read_table(config.parent / "data" / "so101_lerobot" / "data" / "chunk-000" / f"episode_{episode:06d}.parquet")
    return table.column("timestamp").to_numpy().astype(np.float64)


def test_each_segment_lists_its_time_range_robots_and_preview(so101_written: Path) -> None:
    entries = segment_summaries(compile_config(so101_written))
    assert [e.segment for e in entries] == [f"episode_{e:06d}" for e in range(EPISODES)]
    limits = [(c.lower, c.upper) for c in compile_config(so101_written).robots[0].channels]
    for episode, entry in enumerate(entries):
        frame_index, values = _episode(so101_written, episode)
        assert entry.frames == len(frame_index) and entry.episode == episode and entry.path.is_file()
        assert entry.summary is not None and entry.summary.robots == ("so101",)
        timeline, time = entry.summary.timelines  # a LeRobot source's two: frame_index and its timestamps' `time`
        assert (timeline.timeline, timeline.kind) == ("frame_index", "sequence")
        assert (timeline.first, timeline.last) == (int(frame_index[0]), int(frame_index[-1]))
        seconds = _timestamps(so101_written, episode)
        assert (time.timeline, time.kind) == ("time", "duration")
        assert (time.first, time.last) == (round(seconds[0] * 1e9), round(seconds[-1] * 1e9))
        (preview,) = entry.summary.previews
        assert preview.robot == "so101" and preview.joints == tuple(SO101_JOINTS) and preview.rows == len(values)
        assert list(zip(preview.low, preview.high, strict=True)) == limits
        minima, maxima = reference_bands(values)
        for joint in range(len(SO101_JOINTS)):
            assert_codes_match(preview, joint, minima[:, joint], maxima[:, joint])
    lines = [line for line in _manifest_path(so101_written).read_text().splitlines() if '"segment": ' in line]
    assert len(lines) == EPISODES and all(len(line) < 1500 for line in lines), "one line of JSON per segment, ~1 KB"


def _hostile(segments: list[dict[str, Any]]) -> None:
    segments[0]["summary"] = ["not", "a", "mapping"]
    segments[0]["frames"] = "many"
    segments[0]["episode"] = True
    segments[1]["summary"]["timelines"] = [{"timeline": 7, "kind": "sequence", "first": "0", "last": None}, "x"]
    segments[1]["summary"]["preview"][0]["codes"] = "!!!"
    segments[1]["summary"]["robots"] = [1, None, "so101\x1b[2J"]
    segments[2]["summary"]["notes"] = {"a": 1}
    segments[2]["summary"]["preview"][0]["low"] = [float("inf")] * 6  # json writes Infinity
    segments[3].pop("summary")  # as written before summaries, or adopted from its file


def test_a_hand_edited_manifest_is_read_without_an_exception(so101_written: Path, run_cli) -> None:
    path = _manifest_path(so101_written)
    data = json.loads(path.read_text())
    _hostile(data["segments"])
    path.write_text(json.dumps(data))
    entries = segment_summaries(compile_config(so101_written))
    assert all(isinstance(e, SegmentEntry) for e in entries) and len(entries) == EPISODES
    first, second, third, fourth = entries
    assert first.summary is None and first.frames is None and first.episode is None
    assert second.summary is not None and second.summary.timelines == () and second.summary.previews == ()
    assert second.summary.robots == ("so101\\x1b[2J",)  # control characters shown, as errors.shown shows them
    assert third.summary is not None and third.summary.notes == () and third.summary.previews == ()
    assert third.summary.timelines[0].last == third.frames - 1  # type: ignore[operator]
    assert fourth.summary is None and fourth.frames is not None
    result = run_cli("run", str(so101_written))  # and the run still takes it: every segment up to date
    assert result.code == 0 and set(status_lines(result.err).values()) == {"skipped"}


@pytest.mark.parametrize(
    "text", ["[1, 2]", '{"format": 1, "segments": {"a": 1}}', "not json", '{"format": 1, "segments": [7, {"path": 3}]}']
)
def test_a_manifest_of_the_wrong_shape_lists_nothing(so101_written: Path, text: str) -> None:
    path = _manifest_path(so101_written)
    data = json.loads(path.read_text())
    try:
        shaped = json.loads(text)
    except ValueError:
        shaped = None
    if isinstance(shaped, dict):  # ours (it has the key), but its segments are not entries
        shaped.update({k: data[k] for k in ("urdf_pipeline", "application_id", "layout")})
        text = json.dumps(shaped)
    path.write_text(text)
    try:
        entries = segment_summaries(compile_config(so101_written))
    except UserError as refused:  # a file there that is not ours: refused, as run refuses it
        assert "not" in str(refused) and not isinstance(shaped, dict)
        return
    assert entries == []


def test_no_manifest_yet_lists_nothing(examples_dir: Path, tmp_path: Path) -> None:
    config = isolated_examples(examples_dir, tmp_path / "fresh")
    assert segment_summaries(compile_config(config)) == []


def test_the_run_report_holds_each_written_segments_summary(so101_written: Path, run_cli, tmp_path: Path) -> None:
    report = tmp_path / "report.json"
    result = run_cli("run", str(so101_written), "--force", "--report", str(report))
    assert result.code == 0, result.err
    results = {r["label"]: r for r in json.loads(report.read_text())["results"]}
    assert results["model"]["summary"] is None  # the split layout's model: no time, no values
    manifest = {s["segment"]: s["summary"] for s in json.loads(_manifest_path(so101_written).read_text())["segments"]}
    assert {label: r["summary"] for label, r in results.items() if label != "model"} == manifest

"""A LeRobot episode's `timestamp` column (seconds since the episode's start) is the duration timeline `time`, beside
frame_index on every row, its values equal to the parquet's (numpy here); meta/info.json's fps is kept on the plan;
a timestamp that is no time is refused naming the column, the file and the row."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from urdf_pipeline.compile import compile_config
from urdf_pipeline.errors import UserError, Where
from urdf_pipeline.examples import write_lerobot_dataset
from urdf_pipeline.plan import LeRobotSourcePlan
from urdf_pipeline.sources import lerobot

from ..lerobot_layouts import lerobot_panda_config, write_dataset
from ..source_helpers import PANDA_JOINTS, assert_panda_fk, random_panda_q

LENGTHS = [30, 20, 25]


def _jittered_timestamps(dataset: Path, seed: int) -> None:
    """Every data file's timestamp column as a recorder writes it: frame_index / 30 plus up to 5 ms of jitter (float32),
    so that a timeline made from fps alone would differ from it."""
    rng = np.random.default_rng(seed)
    for file in sorted((dataset / "data").glob("**/*.parquet")):  # one iteration per data file
        table = pq.read_table(file)
        frames = table.column("frame_index").to_numpy()
        seconds = (frames / 30 + rng.uniform(0, 0.005, len(frames))).astype(np.float32)
        table = table.set_column(table.schema.get_field_index("timestamp"), "timestamp", pa.array(seconds, pa.float32()))
        pq.write_table(table, file)


def _reference_nanos(dataset: Path, episode: int) -> np.ndarray:
    """The episode's timestamps from its parquet rows, as int64 nanoseconds (float seconds x 1e9, rounded)."""
    table = pa.concat_tables(pq.read_table(f) for f in sorted((dataset / "data").glob("**/*.parquet")))
    table = table.filter(pc.equal(table.column("episode_index"), episode))
    return np.round(table.column("timestamp").to_numpy().astype(np.float64) * 1e9).astype(np.int64)


@pytest.mark.parametrize("layout", ["v2.1", "v3"])
def test_the_time_timeline_holds_the_episode_s_timestamps(layout: str, examples_dir: Path, run_cli) -> None:
    episodes = [random_panda_q(examples_dir, frames, seed=90 + n) for n, frames in enumerate(LENGTHS)]
    stem = f"lerobot_time_{layout.replace('.', '_')}"
    dataset = examples_dir / "data" / stem  # inside the config's folder, where a config may read
    write_dataset(dataset, episodes, layout)
    _jittered_timestamps(dataset, seed=7)
    config = lerobot_panda_config(examples_dir, stem, {"lerobot": str(dataset)})
    assert compile_config(config).review_segment.sources[0].fps == 30.0  # type: ignore[union-attr]

    result = run_cli("run", str(config), "--jobs", "1")
    assert result.code == 0, result.err
    manifest = json.loads(next((examples_dir / "out" / stem).glob("*.manifest.json")).read_text())
    for episode, q in enumerate(episodes):
        nanos = _reference_nanos(dataset, episode)
        assert len(np.unique(np.diff(nanos))) > 1, "the jitter makes the steps uneven"
        recording = examples_dir / "out" / stem / f"episode_{episode:06d}.rrd"
        times = pd.to_timedelta(nanos, unit="ns").tolist()  # a duration timeline reads back as timedeltas
        assert_panda_fk(examples_dir, recording, "time", times, q, [0, len(q) // 2, len(q) - 1])
        assert_panda_fk(examples_dir, recording, "frame_index", list(range(len(q))), q, [0, len(q) - 1])
        summary = next(s["summary"] for s in manifest["segments"] if s["segment"] == f"episode_{episode:06d}")
        time = next(t for t in summary["timelines"] if t["timeline"] == "time")
        assert (time["kind"], time["first"], time["last"]) == ("duration", int(nanos[0]), int(nanos[-1]))
        assert time["seconds"] == pytest.approx((nanos[-1] - nanos[0]) / 1e9), "the segment's real duration"
        frames = next(t for t in summary["timelines"] if t["timeline"] == "frame_index")
        assert (frames["kind"], frames["first"], frames["last"]) == ("sequence", 0, len(q) - 1)


def _plan(root: Path, episode: int = 0, **kept: object) -> LeRobotSourcePlan:
    return LeRobotSourcePlan("state", root, "observation.state", episode, ("a", "b"), Where(root / "c.yaml", 0), **kept)  # type: ignore[arg-type]


def _time_column(plan: LeRobotSourcePlan) -> list[int] | None:
    batches = [chunk.to_record_batch() for chunk in lerobot.open_stream(plan).stream]
    if lerobot.TIME not in batches[0].schema.names:
        return None
    assert all(batch.schema.field(lerobot.TIME).type == pa.duration("ns") for batch in batches)
    return [int(v) for batch in batches for v in batch.column(lerobot.TIME).cast(pa.int64()).to_pylist()]


def test_fps_and_the_timestamp_feature_are_kept_on_the_plan(examples_dir: Path) -> None:
    dataset = examples_dir / "data" / "lerobot_time_fps"
    write_lerobot_dataset(dataset, [random_panda_q(examples_dir, 12, seed=3)], PANDA_JOINTS, fps=50)
    config = lerobot_panda_config(examples_dir, "lerobot_time_fps", {"lerobot": str(dataset)})
    info = dataset / "meta" / "info.json"
    fields = json.loads(info.read_text())
    source = compile_config(config).review_segment.sources[0]
    assert isinstance(source, LeRobotSourcePlan) and (source.fps, source.timed) == (50.0, True)

    info.write_text(json.dumps({**fields, "fps": 29.97}))
    assert compile_config(config).review_segment.sources[0].fps == 29.97  # type: ignore[union-attr]
    without = {k: v for k, v in fields.items() if k != "fps"}
    without["features"] = {k: v for k, v in fields["features"].items() if k != "timestamp"}
    info.write_text(json.dumps(without))
    source = compile_config(config).review_segment.sources[0]
    assert isinstance(source, LeRobotSourcePlan) and (source.fps, source.timed) == (None, False)


def test_a_dataset_without_timestamps_keeps_frame_index_alone(tmp_path: Path) -> None:
    write_lerobot_dataset(tmp_path, [np.zeros((6, 2))], ["a", "b"], fps=10)
    assert _time_column(_plan(tmp_path, timed=False)) is None
    assert _time_column(_plan(tmp_path, timed=True)) == _reference_nanos(tmp_path, 0).tolist()  # float32 seconds, as written


@pytest.mark.parametrize(
    ("bad", "says"),
    [(float("nan"), "not a time: every row needs a finite time"), (1e12, "beyond a timeline's range"), (None, "is empty at row 3")],
)
def test_a_timestamp_that_is_no_time_is_refused_naming_the_file_and_row(bad: float | None, says: str, tmp_path: Path) -> None:
    write_lerobot_dataset(tmp_path, [np.zeros((6, 2))], ["a", "b"])
    file = tmp_path / "data" / "chunk-000" / "episode_000000.parquet"
    table = pq.read_table(file)
    seconds = table.column("timestamp").to_pylist()
    seconds[3] = bad
    pq.write_table(table.set_column(table.schema.get_field_index("timestamp"), "timestamp", pa.array(seconds, pa.float64())), file)
    with pytest.raises(UserError) as refused:
        _time_column(_plan(tmp_path, timed=True))
    message = refused.value.message
    assert "episode 0: column 'timestamp' of" in message and "episode_000000.parquet" in message and says in message, message
    if bad is not None:
        assert "at row 3 (counting from 0)" in message, message


def test_a_declared_timestamp_missing_from_the_data_is_refused(tmp_path: Path) -> None:
    write_lerobot_dataset(tmp_path, [np.zeros((4, 2))], ["a", "b"])
    file = tmp_path / "data" / "chunk-000" / "episode_000000.parquet"
    pq.write_table(pq.read_table(file).drop_columns(["timestamp"]), file)
    with pytest.raises(UserError, match=r"episode_000000\.parquet has no timestamp column, which meta/info\.json's features declare"):
        _time_column(_plan(tmp_path, timed=True))


@pytest.mark.parametrize(("window", "timelines"), [("0.5 s", ("time",)), ("20 rows", ("frame_index",))])
def test_a_trail_window_applies_to_the_timeline_of_its_unit(window: str, timelines: tuple[str, ...], examples_dir: Path) -> None:
    dataset = examples_dir / "data" / "lerobot_time_trails"
    write_lerobot_dataset(dataset, [random_panda_q(examples_dir, 8, seed=5)], PANDA_JOINTS)
    config = lerobot_panda_config(examples_dir, "lerobot_time_trails", {"lerobot": str(dataset)})
    config.write_text(config.read_text() + f"trails:\n- {{link: panda_hand, window: {window}}}\n")
    (trail,) = compile_config(config).trails
    assert trail.timelines == timelines

"""A long segment's progress while it runs: rows out of what the source's metadata says, rate and time left; redrawn on
a terminal, a plain line every few seconds otherwise, nothing under -q."""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.compile import compile_config
from urdf_pipeline.execute import progress_meter
from urdf_pipeline.execute.progress_meter import RowMeter, known_rows, meter_line

from ..dataset_helpers import isolated_examples


def test_the_line_says_rows_of_the_total_the_rate_and_the_time_left() -> None:
    assert (
        meter_line("episode_000", 1_200_000, 3_000_000, 3.0) == "episode_000: 1,200,000 of 3,000,000 rows (40%), 400,000 rows/s, 0:04 left"
    )
    assert meter_line("ep", 10, 36_010, 1.0) == "ep: 10 of 36,010 rows (0%), 10 rows/s, 1:00:00 left"
    assert meter_line("ep", 3_000, 3_000, 1.0) == "ep: 3,000 of 3,000 rows (100%), 3,000 rows/s, finishing"
    assert meter_line("ep", 3_500, 3_000, 1.0) == "ep: 3,500 of 3,000 rows (100%), 3,500 rows/s, finishing"  # metadata was short
    assert meter_line("ep", 0, 3_000, 0.0) == "ep: 0 of 3,000 rows (0%), 0 rows/s, ? left"
    assert meter_line("ep", 5_000, None, 2.0) == "ep: 5,000 rows, 2,500 rows/s"  # CSV, .rrd: no total


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def info_level() -> object:
    logger = logging.getLogger("urdf_pipeline")
    previous = logger.level
    logger.setLevel(logging.INFO)
    yield
    logger.setLevel(previous)


def test_off_a_terminal_a_plain_line_every_interval(caplog: pytest.LogCaptureFixture, info_level: object) -> None:
    clock, stream = _Clock(), io.StringIO()
    meter = RowMeter("episode_000", 1_000, stream=stream, clock=clock)
    with caplog.at_level(logging.INFO, logger="urdf_pipeline"):
        meter.add(100)  # within the interval: nothing yet
        clock.now += progress_meter.METER_SECONDS
        meter.add(100)
        clock.now += 1.0
        meter.add(100)
        meter.finish()
    assert [r.getMessage() for r in caplog.records] == [
        f"urdf-pipeline: episode_000: 200 of 1,000 rows (20%), {200 / progress_meter.METER_SECONDS:,.0f} rows/s, 0:20 left"
    ]
    assert stream.getvalue() == ""


def test_on_a_terminal_the_line_is_redrawn_and_cleared_at_the_end(caplog: pytest.LogCaptureFixture, info_level: object) -> None:
    clock, terminal = _Clock(), _Terminal()
    meter = RowMeter("ep", 100, stream=terminal, clock=clock)
    for _ in range(3):
        clock.now += 1.0
        meter.add(25)
    logging.getLogger("urdf_pipeline").info("a note while it runs")  # clears the drawn line first
    meter.finish()
    assert terminal.getvalue() == (
        "\rurdf-pipeline: ep: 25 of 100 rows (25%), 25 rows/s, 0:03 left\x1b[K"
        "\rurdf-pipeline: ep: 50 of 100 rows (50%), 25 rows/s, 0:02 left\x1b[K"
        "\rurdf-pipeline: ep: 75 of 100 rows (75%), 25 rows/s, 0:01 left\x1b[K"
        "\r\x1b[K"
    )
    assert [r.getMessage() for r in caplog.records] == ["a note while it runs"]


def test_nothing_when_the_logger_is_quiet(caplog: pytest.LogCaptureFixture) -> None:
    logger = logging.getLogger("urdf_pipeline")
    previous = logger.level
    logger.setLevel(logging.WARNING)  # -q
    try:
        clock, terminal = _Clock(), _Terminal()
        meter = RowMeter("ep", 100, stream=terminal, clock=clock)
        clock.now += 60
        meter.add(50)
        meter.finish()
    finally:
        logger.setLevel(previous)
    assert terminal.getvalue() == "" and not caplog.records


def test_the_total_comes_from_each_kind_s_metadata(examples_dir: Path, allow_examples: Path) -> None:
    demo = compile_config(examples_dir / "demo.yaml")
    assert known_rows(demo.segments[0].sources[0], None) == 300  # the parquet footer
    aloha = compile_config(examples_dir / "aloha_bimanual.yaml")
    assert known_rows(aloha.segments[1].sources[0], None) == 150  # the HDF5 dataset's shape (episode 1 has 300 // 2 rows)
    so101 = compile_config(examples_dir / "so101_lerobot.yaml")
    assert known_rows(so101.segments[0].sources[0], None) == 300  # the LeRobot episode's length in its metadata
    assert known_rows(so101.segments[0].sources[0], 123) == 123  # as the dataset plan says it
    ur5 = compile_config(examples_dir / "ur5_ros2_bag.yaml")
    assert known_rows(ur5.segments[0].sources[0], None) == 300  # the MCAP summary's message count


def _long_source(config: Path, rows: int) -> None:
    """The demo's parquet log made `rows` long: long enough for several blocks through the FK."""
    from urdf_pipeline.examples import panda_raw_values, read_urdf, write_joint_parquet

    data = config.parent / "data" / "episode_000.parquet"
    data.unlink()
    _, panda = read_urdf(config.parent / "robots" / "panda.urdf")
    write_joint_parquet(data, panda_raw_values(rows, panda))


def test_a_run_shows_progress_lines_off_a_terminal_and_none_under_quiet(
    allow_examples: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(progress_meter, "METER_SECONDS", 0.0)  # every block: the test need not wait
    config = isolated_examples(allow_examples, tmp_path / "long", "demo.yaml")
    _long_source(config, 10_000)
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    lines = [line for line in result.err.splitlines() if " of 10,000 rows (" in line]
    assert lines and all(line.startswith("urdf-pipeline: episode_000: ") and "rows/s" in line for line in lines), result.err
    assert "\r" not in result.err
    quiet = run_cli("-q", "run", str(config), "--force")
    assert quiet.code == 0 and quiet.err == ""


def test_a_many_segment_run_has_the_run_s_progress_not_a_meter_per_segment(
    allow_examples: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Parallel workers' meters would garble the run's own progress bar: the decision is one meter for a one-segment run."""
    monkeypatch.setattr(progress_meter, "METER_SECONDS", 0.0)
    config = isolated_examples(allow_examples, tmp_path / "many")
    result = run_cli("run", str(config), "--episodes", "0:2", "--jobs", "1")
    assert result.code == 0, result.err
    assert "[2/3] " in result.err and " rows/s" not in result.err


def test_values_are_counted_once_per_source_however_many_robots_it_drives(
    allow_examples: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(progress_meter, "METER_SECONDS", 0.0)
    config = isolated_examples(allow_examples, tmp_path / "two", "bimanual_pandas.yaml")
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    counts = [int(line.split(": ")[2].split(" of ")[0].replace(",", "")) for line in result.err.splitlines() if " of 300 rows (" in line]
    assert counts and max(counts) == 300 and np.all(np.diff(counts) > 0), result.err

"""`snapshot`'s choices made before any viewer starts: which times, which segment, which robot, which files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.render.frames import Timeline
from urdf_pipeline.render.segment_pictures import _time_label, picture_times, time_caption

from ..dataset_helpers import isolated_examples

FRAMES = Timeline("frame_index", "sequence")
TIMES = np.arange(0, 300, dtype=np.int64)


def test_default_times_are_first_middle_last() -> None:
    assert picture_times(None, FRAMES, TIMES) == [0, 149, 299]
    assert picture_times(None, FRAMES, np.array([5], dtype=np.int64)) == [5], "one row: one picture"


def test_times_are_keywords_or_values_in_order_without_repeats() -> None:
    assert picture_times("last, 10,first,10", FRAMES, TIMES) == [299, 10, 0]


@pytest.mark.parametrize(
    ("text", "message"), [("300", "outside the segment's frame_index range 0 .. 299"), ("1.5", "not an integer"), (",", "give one or more")]
)
def test_bad_times_are_user_errors(text: str, message: str) -> None:
    with pytest.raises(UserError, match=message):
        picture_times(text, FRAMES, TIMES)


def test_duration_and_timestamp_times_are_seconds() -> None:
    seconds = np.array([0, 500_000_000, 2_000_000_000], dtype=np.int64)
    assert picture_times("0.5", Timeline("t", "duration"), seconds) == [500_000_000]
    stamps = seconds + 1_700_000_000 * 10**9
    assert picture_times("1700000000.5", Timeline("ts", "timestamp"), stamps) == [1_700_000_000_500_000_000]
    assert picture_times("2023-11-14T22:13:22Z", Timeline("ts", "timestamp"), stamps) == [1_700_000_002 * 10**9]
    with pytest.raises(UserError, match=r"range 2023-11-14T22:13:20.000Z \.\. 2023-11-14T22:13:22.000Z"):
        picture_times("first,1800000000", Timeline("ts", "timestamp"), stamps)


def test_a_recording_without_motion_has_one_picture() -> None:
    assert picture_times(None, None, np.zeros(0, dtype=np.int64)) == [None]
    with pytest.raises(UserError, match="nothing moves"):
        picture_times("first", None, np.zeros(0, dtype=np.int64))


def test_file_names_say_the_time() -> None:
    assert _time_label(FRAMES, 450) == "frame_index-450"
    assert _time_label(Timeline("t", "duration"), 1_500_000_000) == "t-1.500s"
    assert _time_label(Timeline("ts", "timestamp"), 1_700_000_000_123_000_000) == "ts-2023-11-14T22-13-20.123Z"
    assert _time_label(None, None) == "static"


def test_captions_say_the_time_on_its_timeline() -> None:
    assert time_caption(FRAMES, 450) == "frame_index 450"
    assert time_caption(Timeline("t", "duration"), 1_500_000_000) == "t 1.500 s"
    assert time_caption(Timeline("ts", "timestamp"), 1_700_000_000_123_000_000) == "ts 2023-11-14T22:13:20.123Z"
    assert time_caption(None, None) == "static: the recording has no temporal transform"
    assert time_caption(Timeline("frame\n::error::x\u202e", "sequence"), 3) == "frame\\n::error::x\\u202e 3", (
        "a timeline name from data, escaped"
    )


@pytest.fixture
def unwritten(examples_dir: Path, tmp_path: Path, allow_examples: Path) -> Path:
    """The demo config in a folder of its own: nothing written yet."""
    return isolated_examples(examples_dir, tmp_path / "demo", "demo.yaml")


def test_a_recording_not_written_yet_is_named(unwritten: Path, run_cli) -> None:
    result = run_cli("snapshot", str(unwritten))
    assert result.code == 1
    assert result.err.count("\n") == 1 and "no recording at" in result.err and f"urdf-pipeline run {unwritten}" in result.err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--view", "arms"], "--view arms: no such robot (robots: arm; or 'scene') (did you mean 'arm'?)"),
        (["--segment", "episode_001"], "--segment episode_001: no such segment (segments: episode_000)"),
    ],
)
def test_unknown_robots_and_segments_are_user_errors(unwritten: Path, run_cli, args: list[str], message: str) -> None:
    result = run_cli("snapshot", str(unwritten), *args)
    assert result.code == 1 and message in result.err, result.err


@pytest.mark.parametrize(
    "args",
    [
        ["snapshot", "CONFIG", "--size", "big"],
        ["plan", "CONFIG", "--size", "320x240"],
        ["diff", "CONFIG", "CONFIG", "--size", "320x240"],
    ],
)
def test_bad_sizes_and_sizes_without_render_are_usage_errors(unwritten: Path, run_cli, args: list[str]) -> None:
    result = run_cli(*[str(unwritten) if a == "CONFIG" else a for a in args])
    assert result.code == 2, result.err


def test_a_file_that_is_not_a_picture_is_never_overwritten(examples_dir: Path, written: dict[str, Path], tmp_path: Path, run_cli) -> None:
    """Checked before the viewer starts: a wrong -o costs nothing."""
    victim = tmp_path / "episode_000.scene.frame_index-0.png"
    victim.write_text("notes, not a picture")
    result = run_cli("snapshot", str(examples_dir / "demo.yaml"), "--at", "first", "-o", str(tmp_path))
    assert result.code == 1 and f"{victim} exists and is not a PNG picture" in result.err
    assert victim.read_text() == "notes, not a picture"

"""The manifest's per-segment summary (execute/ranges_and_preview.py): time ranges, notes and the joint-value preview,
checked against pyarrow and numpy computed here, independently of the run; and read back from hostile JSON."""

from __future__ import annotations

import base64
import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from urdf_pipeline.compile import compile_config
from urdf_pipeline.errors import Where
from urdf_pipeline.execute.manifest_entry import (
    BUCKETS,
    NOTE_LIMIT,
    NOTES,
    PREVIEW_JOINTS,
    JointPreview,
    SegmentSummary,
    TimeRange,
    iso_time,
)
from urdf_pipeline.execute.ranges_and_preview import FINE_BUCKETS, TimeRanges, ValuePreview, segment_summary
from urdf_pipeline.plan import JointChannel

from ..dataset_helpers import edit_config, isolated_examples

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

HERE = Where(Path("test.yaml"), 1)


def _channel(name: str, lower: float | None, upper: float | None) -> JointChannel:
    return JointChannel(name, name, 0, "rad", 1.0, 1.0, 0.0, lower, upper, 0.0, HERE)


def _rows_per_fine_bucket(rows: int) -> int:
    """The smallest power of two w with rows <= FINE_BUCKETS * w (the width the folding ends with)."""
    width = 1
    while rows > FINE_BUCKETS * width:
        width *= 2
    return width


def reference_bands(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(buckets x joints) min and max by hand: row r falls in fine bucket r // w, which goes to the stored bucket its
    first row falls in; NaN ignored."""
    rows = len(values)
    buckets, width = min(BUCKETS, rows), _rows_per_fine_bucket(rows)
    owner = ((np.arange(rows) // width) * width * buckets) // rows
    minima = np.array([np.nanmin(values[owner == b], axis=0) for b in range(buckets)])
    maxima = np.array([np.nanmax(values[owner == b], axis=0) for b in range(buckets)])
    return minima, maxima


def assert_codes_match(preview: JointPreview, joint: int, minima: np.ndarray, maxima: np.ndarray) -> None:
    """The stored codes hold [min, max] of each bucket within one uint8 step of the joint's scale."""
    low, high = preview.low[joint], preview.high[joint]
    step = (high - low) / 255
    lows, highs = preview.codes_of(joint)
    got_min = low + np.frombuffer(lows, dtype=np.uint8) * step
    got_max = low + np.frombuffer(highs, dtype=np.uint8) * step
    expected_min, expected_max = np.clip(minima, low, high), np.clip(maxima, low, high)
    assert np.all(got_min <= expected_min + 1e-9) and np.all(expected_min - got_min <= step + 1e-9)
    assert np.all(got_max >= expected_max - 1e-9) and np.all(got_max - expected_max <= step + 1e-9)


def _folded(values: np.ndarray, channels: tuple[JointChannel, ...], sizes: list[int], left_out: np.ndarray | None = None) -> ValuePreview:
    preview = ValuePreview("robot", channels)
    start = 0
    for size in sizes:
        stop = min(start + size, len(values))
        preview.add(values[start:stop], None if left_out is None else left_out[start:stop])
        start = stop
    assert start == len(values)
    return preview


@pytest.mark.parametrize("rows", [1, 5, 31, 32, 33, 900, 1024, 1025, 5000, 70_001])
def test_the_preview_is_numpy_by_hand_whatever_the_batches(rows: int) -> None:
    rng = np.random.default_rng(rows)
    channels = (_channel("a", -1.0, 1.0), _channel("b", -3.0, 3.0), _channel("c", None, None))
    values = np.cumsum(rng.normal(0, 0.05, size=(rows, 3)), axis=0)
    sizes = list(rng.integers(1, 3000, size=rows)) if rows < 10_000 else [2048] * (rows // 2048 + 1)
    preview = _folded(values, channels, sizes).result()
    assert preview is not None and preview.rows == rows and preview.buckets == min(BUCKETS, rows)
    assert preview.joints == ("a", "b", "c") and preview.limited == (True, True, False)
    assert preview.low[:2] == (-1.0, -3.0) and preview.high[:2] == (1.0, 3.0)
    if rows > 1:  # the joint without limits is scaled to the range it moved through
        assert (preview.low[2], preview.high[2]) == (values[:, 2].min(), values[:, 2].max())
    minima, maxima = reference_bands(values)
    for joint in range(3):
        assert_codes_match(preview, joint, minima[:, joint], maxima[:, joint])
    same = _folded(values, channels, [len(values)]).result()  # one batch: the very same codes
    assert same is not None and same.codes == preview.codes


def test_the_fold_stays_within_its_buckets_however_long_the_recording() -> None:
    preview = ValuePreview("robot", (_channel("a", -1.0, 1.0),))
    block = np.linspace(-1, 1, 2048)[:, None]
    for _ in range(600):  # 1.2 M rows
        preview.add(block, None)
    assert preview.minima.shape == (FINE_BUCKETS, 1) and preview.rows == 600 * 2048
    result = preview.result()
    assert result is not None and result.rows == 600 * 2048
    lows, highs = result.codes_of(0)
    assert set(lows) == {0} and set(highs) == {255}  # every bucket spans many blocks: the whole range


def test_rows_left_out_and_not_finite_show_nothing_but_keep_their_place() -> None:
    values = np.linspace(0, 1, 64)[:, None].repeat(2, axis=1)
    values[:, 1] = np.nan  # a joint without a single value
    left_out = np.zeros(64, dtype=bool)
    left_out[:2] = True  # rows 0 and 1: bucket 0 of 32
    preview = _folded(values, (_channel("a", 0.0, 1.0), _channel("b", 0.0, 1.0)), [10, 54], left_out).result()
    assert preview is not None and preview.rows == 64
    lows, highs = preview.codes_of(0)
    assert (lows[0], highs[0]) == (255, 0)  # empty: min above max
    assert set(preview.codes_of(1)[0]) == {255} and set(preview.codes_of(1)[1]) == {0}


@pytest.mark.filterwarnings("error")
def test_values_far_beyond_any_scale_and_joints_that_never_move_give_codes_not_warnings() -> None:
    values = np.array([[1e300, 5.0, -1e308], [-1e300, 5.0, 1e308], [0.0, 5.0, 0.0]])
    preview = _folded(values, (_channel("a", -1.0, 1.0), _channel("still", None, None), _channel("wild", None, None)), [2, 1]).result()
    assert preview is not None and preview.buckets == 3
    assert preview.codes_of(0) == (bytes([255, 0, 127]), bytes([255, 0, 128]))  # clipped to the ends of its limits
    assert preview.low[1] < 5.0 < preview.high[1] and set(preview.codes_of(1)[0]) == {127}  # mid-scale
    assert all(len(band) == 3 for band in preview.codes_of(2))


def test_eight_joints_that_move_most_against_their_limits_in_the_robots_order() -> None:
    count = 11
    channels = tuple(_channel(f"j{i}", -1.0, 1.0) for i in range(count - 1)) + (_channel("wheel", None, None),)
    rng = np.random.default_rng(3)
    amplitude = np.array([0.1, 0.9, 0.2, 0.8, 0.05, 0.7, 0.6, 0.5, 0.4, 0.3, 100.0])  # the wheel turns many times
    values = rng.uniform(-1, 1, size=(500, count)) * amplitude
    preview = _folded(values, channels, [500]).result()
    assert preview is not None and len(preview.joints) == PREVIEW_JOINTS
    assert preview.joints == ("j1", "j3", "j5", "j6", "j7", "j8", "j9", "wheel")  # j0, j2, j4 moved least


def test_time_ranges_json_and_notes_are_bounded() -> None:
    stamp = TimeRange("timestamp", "timestamp", 1_700_000_000_000_000_001, 1_700_000_030_500_000_000)
    assert stamp.seconds == pytest.approx(30.5) and stamp.first_iso == "2023-11-14T22:13:20.000000001Z"
    assert iso_time(-1) == "1969-12-31T23:59:59.999999999Z"
    assert TimeRange("frame_index", "sequence", 0, 9).seconds is None
    notes = tuple(f"note {i} \x1b[31m{'x' * 1000}\n" for i in range(NOTES + 5))
    summary = segment_summary(("arm",), TimeRanges(), [], notes)
    assert len(summary.notes) == NOTES and summary.notes_left_out == 5
    assert all(len(n) <= NOTE_LIMIT and "\x1b" not in n and "\n" not in n for n in summary.notes)
    assert SegmentSummary.from_json(json.loads(json.dumps(summary.as_json()))) == summary


def _summary_of(config: Path, segment: int = 0) -> dict[str, Any]:
    manifest = next(config.parent.glob("out/**/*.manifest.json"))
    return json.loads(manifest.read_text())["segments"][segment]["summary"]


def _demo_values_by_hand(parquet: Path) -> np.ndarray:
    """configs/demo.yaml's corrections, written out: degrees (the finger mm), j2's sign, j3's offset."""
    state = np.asarray(pq.read_table(parquet).column("observation.state").combine_chunks().flatten(), dtype=np.float64).reshape(-1, 8)
    values = np.column_stack([np.radians(state[:, :7]), state[:, 7] / 1000])
    values[:, 1] *= -1
    values[:, 2] += 0.1
    return values


def test_the_demo_run_records_its_summary_in_the_manifest(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path, "demo.yaml")
    assert run_cli("run", str(config)).code == 0
    summary = _summary_of(config)
    frame_index = pq.read_table(tmp_path / "data" / "episode_000.parquet").column("frame_index").to_numpy()
    assert summary["timelines"] == [
        {"timeline": "frame_index", "kind": "sequence", "first": int(frame_index[0]), "last": int(frame_index[-1])}
    ]
    assert summary["robots"] == ["arm"] and summary["notes"] == [] and summary["notes_left_out"] == 0
    (preview,) = SegmentSummary.from_json(summary).previews  # type: ignore[union-attr]
    values = _demo_values_by_hand(tmp_path / "data" / "episode_000.parquet")
    assert preview.rows == len(values) and len(preview.joints) == 8
    limits = [(c.lower, c.upper) for c in compile_config(config).robots[0].channels]
    assert list(zip(preview.low, preview.high, strict=True)) == limits
    minima, maxima = reference_bands(values)
    for joint in range(8):
        assert_codes_match(preview, joint, minima[:, joint], maxima[:, joint])
    assert len(summary["preview"][0]["codes"]) <= 700  # 8 joints x 32 buckets x (min, max): 512 bytes in base64
    assert len(json.dumps(summary)) < 1600


def test_a_timestamp_index_gives_seconds_and_dates(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path, "demo.yaml")
    edit_config(config, lambda data: data["sources"]["arm_state"].update(index={"timestamp": "timestamp", "unit": "s"}))
    assert run_cli("run", str(config)).code == 0
    (timeline,) = _summary_of(config)["timelines"]
    seconds = pq.read_table(tmp_path / "data" / "episode_000.parquet").column("timestamp").to_numpy()
    assert timeline["timeline"] == "timestamp" and timeline["kind"] == "timestamp"
    assert abs(timeline["first"] - seconds[0] * 1e9) <= 1e3 and abs(timeline["last"] - seconds[-1] * 1e9) <= 1e3  # float s -> int ns
    assert timeline["seconds"] == pytest.approx(seconds[-1] - seconds[0], abs=1e-6)
    assert timeline["first_iso"] == iso_time(timeline["first"]) and timeline["first_iso"].startswith("1970-01-01T00:00:00")


def test_a_config_that_clamps_lists_its_notes(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path, "demo.yaml")

    def clamp(data: dict[str, Any]) -> None:
        data["robots"]["arm"]["joints"]["map"]["j1"] = {"joint": "panda_joint1", "scale": 4.0}
        data["robots"]["arm"]["joints"]["limits"]["on_violation"] = "clamp"

    edit_config(config, clamp)
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    summary = _summary_of(config)
    assert any("panda_joint1" in note and "clamped" in note for note in summary["notes"]), summary["notes"]
    preview = SegmentSummary.from_json(summary).previews[0]  # type: ignore[union-attr]
    lows, highs = preview.codes_of(0)
    assert min(lows) == 0 and max(highs) == 255  # clamped onto both limits


def _valid_summary() -> dict[str, Any]:
    preview = JointPreview("arm", 100, 2, ("a", "b"), (-1.0, 0.0), (1.0, 2.0), (True, False), bytes([0, 10, 20, 255, 3, 4, 5, 6]))
    times = (TimeRange("frame_index", "sequence", 0, 99), TimeRange("t", "timestamp", 10, 2_000_000_000))
    return SegmentSummary(("arm",), times, ("a note",), 0, (preview,)).as_json()


HOSTILE = [None, True, -1, 1.5, 10**30, float("nan"), "", "\x1b[2J" + "z" * 5000, "!!notbase64", [], [None, 1], {}, {"a": 1}]


def _paths(value: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every place in a JSON value, containers included."""
    found = [path]
    if isinstance(value, dict):
        for key, item in value.items():
            found += _paths(item, (*path, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            found += _paths(item, (*path, index))
    return found


def _replaced(value: Any, path: tuple[Any, ...], new: Any) -> Any:
    if not path:
        return new
    copied = copy.deepcopy(value)
    target = copied
    for step in path[:-1]:
        target = target[step]
    target[path[-1]] = new
    return copied


def test_any_value_anywhere_in_a_hand_edited_summary_is_dropped_not_raised() -> None:
    valid = _valid_summary()
    assert SegmentSummary.from_json(valid) == SegmentSummary.from_json(json.loads(json.dumps(valid)))
    for path in _paths(valid):
        for hostile in HOSTILE:
            read = SegmentSummary.from_json(_replaced(valid, path, hostile))
            assert read is None or isinstance(read, SegmentSummary)
            if read is not None:  # whatever is kept is typed and bounded
                assert all(isinstance(n, str) and len(n) <= NOTE_LIMIT for n in read.notes + read.robots)
                assert all(isinstance(t.first, int) and t.first <= t.last for t in read.timelines)
                assert all(len(p.codes) == len(p.joints) * 2 * p.buckets for p in read.previews)


def test_a_preview_whose_codes_do_not_fit_its_joints_is_dropped() -> None:
    summary = _valid_summary()
    summary["preview"][0]["codes"] = base64.b64encode(bytes(7)).decode()
    summary["timelines"][1]["first"] = 3 * 10**9  # after its last
    read = SegmentSummary.from_json(summary)
    assert read is not None and read.previews == () and [t.timeline for t in read.timelines] == ["frame_index"]


def test_a_source_out_of_order_is_summarised_once_sorted(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    """Rows found out of time order part-way (after blocks went through the FK) make the run read the source again,
    whole and sorted: the summary is the second attempt's alone (no rows counted twice), in time order."""
    config = isolated_examples(examples_dir, tmp_path, "demo.yaml")
    demo = pq.read_table(tmp_path / "data" / "episode_000.parquet")
    table = pa.concat_tables([demo] * (6000 // len(demo) + 1)).slice(0, 6000)
    order = np.r_[np.arange(5000), np.arange(5000, 6000)[::-1]]  # the last 1000 rows backwards
    table = table.set_column(0, "frame_index", pa.array(np.arange(6000))).take(order)
    pq.write_table(table, tmp_path / "late.parquet")
    edit_config(config, lambda data: data["sources"]["arm_state"].update(parquet="late.parquet"))
    result = run_cli("run", str(config))
    assert result.code == 0 and "sorted by frame_index" in result.err, result.err
    summary = SegmentSummary.from_json(_summary_of(config))
    assert summary is not None and [(t.first, t.last) for t in summary.timelines] == [(0, 5999)]
    (preview,) = summary.previews
    assert preview.rows == 6000
    values = _demo_values_by_hand(tmp_path / "late.parquet")[np.argsort(order)]  # in time order
    minima, maxima = reference_bands(values)
    for joint in range(8):
        assert_codes_match(preview, joint, minima[:, joint], maxima[:, joint])

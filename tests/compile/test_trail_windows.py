"""A trail window is refused at its key when a timeline cannot hold it (int64 nanoseconds on a time timeline, int64
rows on a sequence timeline, at least 1 ns), and every window `validate` accepts makes a blueprint Rerun reads back:
the extreme accepted windows are run, and the .rbl is read with Rerun's own reader and checked by `rerun rrd verify`."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from urdf_pipeline.compile.trails import parse_window, window_beyond
from urdf_pipeline.examples import panda_raw_values, write_joint_parquet
from urdf_pipeline.urdf.model import read_urdf

from ..execute.test_fk_against_pinocchio import variant

LARGEST_SECONDS = "9223372036 s"  # int(9223372036 * 1e9) < 2^63 - 1: the largest whole number of seconds
LARGEST_ROWS = "9223372036854774784 rows"  # the largest float below 2^63
ACCEPTED = [LARGEST_SECONDS, "9223372036.854 s", "153722867 min", LARGEST_ROWS, "0.000001 ms", "1 rows", "2 s"]
REFUSED = {
    "9223372037 s": "longer than a time timeline holds",
    "153722868 min": "longer than a time timeline holds",
    "1" + "0" * 400 + " s": "longer than a time timeline holds",  # a float of inf
    "9223372036854775807 rows": "more rows than a sequence timeline holds",  # 2^63 as a float
    "1" + "0" * 400 + " rows": "more rows than a sequence timeline holds",
    "0.0000001 ms": "shorter than 1 ns",
}


@pytest.mark.parametrize("text", ACCEPTED)
def test_an_accepted_window_is_one_rerun_s_blueprint_holds(text: str) -> None:
    parsed = parse_window(text)
    assert parsed is not None and window_beyond(*parsed) is None
    span, unit = parsed
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # Rerun drops a range it cannot hold with a RerunWarning: that would fail here
        start = (
            rrb.TimeRangeBoundary.cursor_relative(seq=-int(span))
            if unit == "rows"
            else rrb.TimeRangeBoundary.cursor_relative(seconds=-span)
        )
        rrb.Spatial3DView(origin="/", time_ranges=[rrb.VisibleTimeRange("t", start=start, end=rrb.TimeRangeBoundary.cursor_relative())])


@pytest.mark.parametrize("text", sorted(REFUSED))
def test_a_window_beyond_a_timeline_is_refused(text: str) -> None:
    parsed = parse_window(text)
    assert parsed is not None
    assert REFUSED[text] in (window_beyond(*parsed) or "")


def _blueprint_start(blueprint: Path) -> int:
    """The 3D views' visible range start, read back with Rerun's own reader of the blueprint store."""
    reader = RrdReader(blueprint)
    starts = [
        row["VisibleTimeRanges:ranges"][0]["range"]["start"]
        for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks()
        if "VisibleTimeRanges:ranges" in (batch := chunk.to_record_batch()).schema.names
        for row in batch.to_pylist()
    ]
    assert starts and len(set(starts)) == 1, starts
    return int(starts[0])


@pytest.mark.parametrize(
    ("window", "index", "start"),
    [
        (LARGEST_ROWS, "frame_index", -9223372036854774784),
        ("1 rows", "frame_index", -1),
        (LARGEST_SECONDS, {"timestamp": "timestamp", "unit": "s"}, -int(9223372036 * 1e9)),
        ("0.000001 ms", {"timestamp": "timestamp", "unit": "s"}, -1),
    ],
)
def test_a_run_with_the_extreme_windows_writes_a_blueprint_rerun_reads_back(
    window: str, index: object, start: int, examples_dir: Path, run_cli
) -> None:
    _, panda = read_urdf(examples_dir / "robots" / "panda.urdf")
    write_joint_parquet(examples_dir / "data" / "trail_windows.parquet", panda_raw_values(8, panda))

    def edit(data: dict) -> None:
        data["sources"]["arm_state"].update(parquet="data/trail_windows.parquet", index=index)
        data["trails"] = [{"link": "panda_hand", "window": window}]

    name = f"trail_window_{abs(start)}"
    result = run_cli("run", str(variant(examples_dir, "demo.yaml", name, edit)))
    assert result.code == 0, result.err
    blueprint = Path(result.out.strip()).with_name(f"{name}.rbl")
    assert _blueprint_start(blueprint) == start
    rerun = Path(sys.executable).with_name("rerun")
    verified = subprocess.run([str(rerun), "rrd", "verify", str(blueprint)], capture_output=True, text=True, timeout=60, check=False)
    assert verified.returncode == 0, verified.stderr

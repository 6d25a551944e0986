"""Link positions read from a recording, composed with numpy, against an independent per-row composition
(tests/rrd_frames.py) of the same recordings: the demo (sequence timeline) and two Pandas (timestamp timeline)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from urdf_pipeline.compile import compile_config
from urdf_pipeline.render import frames
from urdf_pipeline.render.frames import Timeline, read_transforms, transform_timelines
from urdf_pipeline.render.plan_pictures import robot_frames

from ..rrd_frames import read_frames


@pytest.mark.parametrize(
    ("name", "timeline"), [("demo", Timeline("frame_index", "sequence")), ("bimanual_pandas", Timeline("timestamp", "timestamp"))]
)
def test_positions_match_a_row_by_row_composition(examples_dir: Path, written: dict[str, Path], name: str, timeline: Timeline) -> None:
    plan = compile_config(examples_dir / f"{name}.yaml")
    chunks = RrdReader(written[name]).stream().to_chunks()
    assert transform_timelines(chunks, [r.fk_entity for r in plan.robots]) == [timeline]
    transforms = read_transforms(chunks, timeline)
    times = transforms.times
    assert len(times) == 300
    links = robot_frames(plan.robots)
    picked = times[[0, 1, 150, 299]]
    positions = transforms.positions(plan.root_frame, links, picked)
    reference = read_frames(written[name], timeline.name)
    for row, time in enumerate(picked):
        for column, link in enumerate(links):  # the reference keys timestamps as integer nanoseconds, as frames.py does
            expected = reference.world_pose(link, int(time), plan.root_frame)[:3, 3]
            assert np.allclose(positions[row, column], expected, atol=1e-5), (link, time)


def test_between_rows_the_latest_row_holds_and_unknown_frames_are_nan(examples_dir: Path, written: dict[str, Path]) -> None:
    plan = compile_config(examples_dir / "demo.yaml")
    transforms = read_transforms(RrdReader(written["demo"]).stream().to_chunks(), Timeline("frame_index", "sequence"))
    at_rows = transforms.positions("world", ["panda_hand", "no_such_frame", "world"], np.array([10, 11]))
    between = transforms.positions("world", ["panda_hand"], np.array([10]))
    assert np.allclose(at_rows[0, 0], between[0, 0])
    assert np.isnan(at_rows[:, 1]).all(), "a frame the recording does not place"
    assert np.allclose(at_rows[:, 2], 0.0), "the root sits at the origin"
    assert plan.root_frame == "world"


def test_without_a_timeline_the_static_pose_is_composed(written: dict[str, Path]) -> None:
    transforms = read_transforms(RrdReader(written["demo"]).stream().to_chunks(), None)
    (only,) = transforms.sampled_times()
    link0 = transforms.positions("world", ["panda_link0"], np.array([only]))
    assert np.allclose(link0, [[[0.0, 0.0, 0.5]]]), "the calibration edge world -> panda_link0"


def test_long_segments_are_sampled_evenly_with_both_ends(written: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    transforms = read_transforms(RrdReader(written["demo"]).stream().to_chunks(), Timeline("frame_index", "sequence"))
    monkeypatch.setattr(frames, "MAX_TIMES", 7)
    sampled = transforms.sampled_times()
    assert len(sampled) == 7 and sampled[0] == 0 and sampled[-1] == 299
    assert np.all(np.diff(sampled) > 0)

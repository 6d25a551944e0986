"""`urdf_pipeline.live`: a simulated 1 kHz control loop pushes the contract config's raw values; the saved recording's
poses equal pinocchio's for sampled pushes, and what a stream cannot be refused for is reported, not raised."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import urdf_pipeline
from urdf_pipeline.errors import UserError

from ..compile.test_temporal_edges import POSE_NAMES, TEMPORAL_EDGE, expected_pose, random_poses
from ..edge_helpers import panda_config, write_config
from ..execute.test_fk_against_pinocchio import (
    PANDA_ARM,
    assert_poses_match,
    check_robot,
    panda_contract_raw,
    panda_joint_values,
    random_within_limits,
)
from ..local_processes import free_port
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames

START_S = 1_800_000_000.0  # seconds since the epoch of the first push
NAMES = ["j1", "j2", "j3", "j4", "j5", "j6", "j7", "finger"]


@pytest.fixture(scope="module")
def panda(examples_dir: Path) -> tuple[Path, PinocchioRobot]:
    return examples_dir / "demo.yaml", PinocchioRobot(examples_dir / "robots" / "panda.urdf")


def world_from_base() -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, 0.5]  # the demo's calibration edge
    return pose


def test_a_1khz_loop_of_pushes_matches_pinocchio(panda: tuple[Path, PinocchioRobot], tmp_path: Path) -> None:
    config, reference = panda
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=400, seed=31)
    raw = panda_contract_raw(q)
    saved = tmp_path / "loop.rrd"
    began = time.perf_counter()
    with urdf_pipeline.live(config, save=saved) as view:
        for k, row in enumerate(raw):
            if k % 2:  # the two forms a loop has: a sequence in the source's names order, or a mapping
                view.push(row, time=START_S + k / 1000)
            else:
                view.push(dict(zip(NAMES, row, strict=True)), time=START_S + k / 1000)
            while time.perf_counter() < began + (k + 1) / 1000:  # the loop's own 1 kHz pace
                pass
        assert view.count == 400
    assert view.sent == 400
    frames = read_frames(saved, "time")
    times = [round((START_S + k / 1000) * 1e9) for k in range(400)]
    checked = [0, 1, 57, 200, 399]
    values = [panda_joint_values(row) for row in q]
    assert check_robot(frames, times, reference, values, "", world_from_base(), "world", checked) == len(checked) * 13


def test_push_batch_and_a_caller_recording(panda: tuple[Path, PinocchioRobot], tmp_path: Path) -> None:
    import rerun as rr

    config, reference = panda
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=300, seed=32)
    recording = rr.RecordingStream("mine")
    saved = tmp_path / "batches.rrd"
    recording.save(saved)
    view = urdf_pipeline.live(config, recording, time_kind="sequence", timeline="step", max_delay=0)
    for start in range(0, 300, 100):
        view.push_batch(panda_contract_raw(q[start : start + 100]), np.arange(start, start + 100))
    view.close()
    recording.flush()
    recording.disconnect()
    frames = read_frames(saved, "step")
    values = [panda_joint_values(row) for row in q]
    assert check_robot(frames, list(range(300)), reference, values, "", world_from_base(), "world", [0, 99, 100, 299]) == 4 * 13


def test_wrong_count_and_unknown_names_raise_at_the_first_sample(panda: tuple[Path, PinocchioRobot], tmp_path: Path) -> None:
    config, _ = panda
    with urdf_pipeline.live(config, save=tmp_path / "refused.rrd") as view:
        with pytest.raises(UserError, match=r"was given 7 values; source 'arm_state' has 8 names"):
            view.push([0.0] * 7)
        with pytest.raises(UserError, match=r"names 'j9', not among source 'arm_state''s names"):
            view.push({**dict.fromkeys(NAMES, 0.0), "j9": 1.0})
        with pytest.raises(UserError, match=r"gives no value for 'j4', which the config maps"):
            view.push({name: 0.0 for name in NAMES if name != "j4"})
        assert view.count == 0


def test_values_beyond_the_limits_are_reported_not_refused(panda: tuple[Path, PinocchioRobot], tmp_path: Path, caplog) -> None:
    config, _ = panda
    saved = tmp_path / "beyond.rrd"
    caplog.set_level(logging.WARNING, logger="urdf_pipeline")
    with urdf_pipeline.live(config, save=saved, max_delay=0) as view:
        row = np.zeros(8)
        row[3] = -80.0  # panda_joint4 in degrees: within [-176, -4]
        for k in range(50):
            bad = row.copy()
            bad[0] = 200.0 if k % 10 == 0 else 0.0  # j1 beyond 166 deg every tenth sample
            if k == 25:
                bad[5] = np.nan
            view.push(bad, time=START_S + k)
    assert view.sent == 49  # the NaN sample is left out (joints.nan: error), the others shown
    lines = [r.getMessage() for r in caplog.records]
    beyond = [line for line in lines if "panda_joint1" in line and "beyond the URDF limits" in line]
    # the first at once, the rest when the window ends (here: at close), counted once each
    assert "1 of 1 rows" in beyond[0] and "since the view started" in beyond[0] and "cannot refuse" in beyond[0], lines
    assert sum(int(line.split("): ")[1].split(" of ")[0]) for line in beyond) == 5, lines
    assert any("NaN or infinite, the first at row 25" in line and "'panda_joint6'" in line for line in lines), lines
    frames = read_frames(saved, "time")
    assert len(frames.temporal["panda_link1"]) == 49


def test_live_needs_names_it_can_find(tmp_path: Path, examples_dir: Path) -> None:
    text = (examples_dir / "ur5_ros2_bag.yaml").read_text().replace("data/ur5_joint_states.mcap", "data/absent.mcap")
    config = examples_dir / "live_no_names.yaml"
    config.write_text(text)
    with pytest.raises(UserError, match=r"live view without the data needs the names: give names"):
        urdf_pipeline.live(config, save=tmp_path / "x.rrd")


def test_a_pushed_base_pose_is_a_temporal_edge(examples_dir: Path, tmp_path: Path) -> None:
    """One source drives the arm and its moving base (a temporal edge): each push's pose places the whole robot."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=30, seed=37)
    poses = random_poses(30, seed=38)
    data = panda_config(examples_dir, "live_base", "data/not_needed.parquet", [{**TEMPORAL_EDGE, "source": "arm_state"}])
    data["sources"]["arm_state"]["names"] += POSE_NAMES
    data["robots"]["arm"]["joints"]["ignore"] = POSE_NAMES
    config = write_config(examples_dir, "live_base", data)
    saved = tmp_path / "base.rrd"
    with urdf_pipeline.live(config, save=saved, time_kind="sequence") as view:
        view.push_batch(np.concatenate([panda_contract_raw(q), poses], axis=1))
    frames = read_frames(saved, "time")
    for frame in (0, 11, 29):
        world_from_base = expected_pose(poses[frame])
        for link, link_pose in reference.link_poses(panda_joint_values(q[frame])).items():
            assert_poses_match(frames.world_pose(link, frame, "world"), world_from_base @ link_pose, f"{link} at {frame}")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a screen is DISPLAY or WAYLAND_DISPLAY on Linux only")
def test_live_without_a_screen_raises_what_the_command_line_says(examples_dir: Path, tmp_path: Path) -> None:
    """No DISPLAY: `live(config)` raises at once the line `urdf-pipeline live` prints (each in a child, no viewer to reuse)."""
    screenless = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")}
    prelude = f"import sys; from urdf_pipeline.process import rerun_viewer; rerun_viewer.DEFAULT_PORT = {free_port()}\n"
    config = str(examples_dir / "demo.yaml")
    api = f"import urdf_pipeline\ntry:\n    urdf_pipeline.live({config!r})\nexcept urdf_pipeline.ConfigError as e:\n    sys.exit(e.lines()[0])"
    cli = f"from urdf_pipeline.cli import main\nsys.exit(main(['live', '-q', {config!r}, '--from', {str(tmp_path / 'x.mcap')!r}]))"
    said = [
        subprocess.run([sys.executable, "-c", prelude + code], env=screenless, capture_output=True, text=True, timeout=120)
        for code in (api, cli)
    ]
    assert [s.returncode for s in said] == [1, 1], [s.stderr for s in said]
    api_line, cli_line = (s.stderr.splitlines()[-1] for s in said)
    assert api_line == cli_line and api_line.startswith("error: --spawn: cannot start the Rerun viewer: no screen here"), api_line

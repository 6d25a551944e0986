"""The Python API, each call against the command line or pinocchio: load, run, log, forward_kinematics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rerun as rr

import urdf_pipeline
from urdf_pipeline.examples import write_joint_parquet

from ..execute.test_fk_against_pinocchio import (
    PANDA_ARM,
    assert_poses_match,
    panda_contract_raw,
    panda_joint_values,
    random_within_limits,
    variant,
)
from ..execute.test_joint_series import read_series
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames

INVALID = Path(__file__).resolve().parents[1] / "configs" / "invalid"
WORLD_FROM_BASE = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1.0]])  # demo.yaml's calibration edge


@pytest.fixture
def random_demo(examples_dir: Path) -> tuple[Path, np.ndarray, PinocchioRobot]:
    """demo.yaml on random joint values (degrees, a negated joint, an offset, a finger in mm): config, q, reference."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=50, seed=21)
    write_joint_parquet(examples_dir / "data" / "api_panda.parquet", panda_contract_raw(q))
    config = variant(examples_dir, "demo.yaml", "api_panda", lambda d: d["sources"]["arm_state"].update(parquet="data/api_panda.parquet"))
    return config, q, reference


def test_load_gives_the_plan_and_raises_the_cli_messages(examples_dir: Path, run_cli) -> None:
    plan = urdf_pipeline.load(examples_dir / "demo.yaml")
    assert isinstance(plan, urdf_pipeline.Plan) and [r.key for r in plan.robots] == ["arm"]
    invalid = sorted(INVALID.glob("*.yaml"))[0]
    with pytest.raises(urdf_pipeline.ConfigError) as raised:
        urdf_pipeline.load(invalid)
    cli = run_cli("validate", str(invalid))
    assert cli.code == 1
    assert [line for line in cli.err.splitlines() if line.startswith("error:")] == raised.value.lines()


def test_run_writes_and_then_finds_it_up_to_date(random_demo: tuple[Path, np.ndarray, PinocchioRobot]) -> None:
    config, _, _ = random_demo
    written = urdf_pipeline.run(config, jobs=1)
    assert len(written) == 1 and written[0].is_file()
    stamp = written[0].stat().st_mtime_ns
    assert urdf_pipeline.run(config) == written and written[0].stat().st_mtime_ns == stamp  # up to date: not rewritten
    assert urdf_pipeline.run(config, force=True) == written and written[0].stat().st_mtime_ns != stamp


def test_forward_kinematics_equals_pinocchio(random_demo: tuple[Path, np.ndarray, PinocchioRobot]) -> None:
    config, q, reference = random_demo
    kinematics = urdf_pipeline.forward_kinematics(urdf_pipeline.load(config))["arm"]
    assert kinematics.root == "panda_link0" and list(kinematics.times["frame_index"]) == list(range(50))
    matrices = kinematics.matrices()
    assert matrices.shape == (len(kinematics.links), 50, 4, 4)
    compared = 0
    for row in (0, 17, 49):
        for link, expected in reference.link_poses(panda_joint_values(q[row])).items():
            assert_poses_match(matrices[kinematics.links.index(link), row], expected, f"{link} at row {row}")
            compared += 1
    assert compared == 3 * 13


def test_log_sends_the_segment_into_the_callers_recording(random_demo: tuple[Path, np.ndarray, PinocchioRobot], tmp_path: Path) -> None:
    config, q, reference = random_demo
    recording = rr.RecordingStream("my_app", recording_id="my_take")
    saved = tmp_path / "mine.rrd"
    recording.save(saved)
    recording.log("camera/points", rr.Points3D([[0.0, 0.0, 0.0]]))  # the caller's own data, beside ours
    rows = urdf_pipeline.log(config, recording)
    recording.flush()
    recording.disconnect()
    assert rows == {"arm": 50}
    frames = read_frames(saved, "frame_index")
    for row in (0, 49):
        for link, expected in reference.link_poses(panda_joint_values(q[row])).items():
            assert_poses_match(frames.world_pose(link, row, "world"), WORLD_FROM_BASE @ expected, f"{link} at row {row}")


def test_log_sends_the_joint_series_when_the_config_asks(random_demo: tuple[Path, np.ndarray, PinocchioRobot], tmp_path: Path) -> None:
    config, q, _ = random_demo
    config.write_text(config.read_text().replace("output:\n", "output:\n  joint_series: true\n"))
    recording = rr.RecordingStream("my_app", recording_id="my_take")
    saved = tmp_path / "mine.rrd"
    recording.save(saved)
    assert urdf_pipeline.log(config, recording) == {"arm": 50}
    recording.flush()
    recording.disconnect()
    times, values, names = read_series(saved)
    assert names == [*PANDA_ARM, "panda_finger_joint1"]
    assert list(times["frame_index"]) == list(range(50))
    np.testing.assert_allclose(values, q, rtol=0, atol=1e-6)  # the source holds float32 degrees and millimetres


def test_a_config_of_several_segments_needs_the_segment_named(examples_dir: Path) -> None:
    plan = urdf_pipeline.load(examples_dir / "so101_dataset.yaml")
    assert len(plan.dataset.segments) > 1
    with pytest.raises(urdf_pipeline.ConfigError, match="say which with segment= one of"):
        urdf_pipeline.forward_kinematics(plan)
    first = plan.dataset.segments[0].id
    assert set(urdf_pipeline.forward_kinematics(plan, segment=first)) == {r.key for r in plan.robots}


def test_importing_the_package_imports_nothing_heavy() -> None:
    import subprocess
    import sys

    code = "import sys, urdf_pipeline; print(sorted(m for m in ('rerun', 'numpy', 'pyarrow', 'jsonschema') if m in sys.modules))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "[]"

"""`urdf-pipeline init --source`: each joint's unit chosen from a bounded sample (check's) against the URDF limits, with
the reason in a comment; "the config validates" never said of a config whose sample check's rules refuse; without -o,
the printed paths are said to be relative to the current folder."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet

pytestmark = pytest.mark.usefixtures("allow_examples")  # the URDFs are the session's examples

SO101 = "robots/share/example-robot-data/robots/so_arm_description/urdf/so101.urdf"
# so101's six joints in its URDF's order (gripper first), as degrees well inside their limits
_T = np.linspace(0, 6, 300)
DEGREES = np.stack(
    [
        45 + 40 * np.sin(1.5 * _T),  # gripper, -10..100 deg
        120 * np.sin(_T + 2),  # wrist_roll, -157..163 deg
        50 * np.cos(_T + 1),  # wrist_flex, +-95 deg
        60 * np.sin(_T + 1),  # elbow_flex, +-96.8 deg
        70 * np.cos(_T),  # shoulder_lift, +-100 deg
        80 * np.sin(_T),  # shoulder_pan, +-110 deg
    ],
    axis=1,
)
GRIPPER, WRIST_ROLL, SHOULDER_PAN = 0, 1, 5


def init(run_cli, examples_dir: Path, tmp_path: Path, values: np.ndarray | None, *extra: str) -> tuple[dict, str, str]:
    """init for so101 with a parquet source of `values` (or the example LeRobot dataset, in degrees, for None)."""
    if values is None:
        source = f"lerobot:{examples_dir / 'data' / 'so101_lerobot'}"
    else:
        write_joint_parquet(tmp_path / "data.parquet", values)
        source = f"parquet:{tmp_path / 'data.parquet'}#observation.state"
    config = tmp_path / "so101.yaml"
    result = run_cli("init", "--urdf", str(examples_dir / SO101), "--source", source, "-o", str(config), *extra)
    assert result.code == 0, result.err
    text = config.read_text()
    return yaml.safe_load(text), text, result.err


def joints_of(data: dict) -> dict:
    (robot,) = data["robots"].values()
    return robot["joints"]


def unit_line(text: str) -> str:
    return next(line for line in text.splitlines() if line.strip().startswith("unit:"))


def test_lerobot_degrees_get_unit_deg_with_the_reason(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    data, text, err = init(run_cli, examples_dir, tmp_path, None)
    joints = joints_of(data)
    assert joints["unit"] == "deg" and all(isinstance(v, str) for v in joints["map"].values())
    assert "sampled values point to degrees for 6 of 6 revolute and continuous joints" in unit_line(text)
    assert text.count("fit the limits only in degrees") == 6
    assert "init: the config validates" in err
    checked = run_cli("check", str(tmp_path / "so101.yaml"))
    assert checked.code == 0, checked.out


def test_radians_stay_radians_and_say_why(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    data, text, err = init(run_cli, examples_dir, tmp_path, np.radians(DEGREES))
    assert joints_of(data)["unit"] == "rad"
    assert "(in degrees they would barely leave zero)" in text and "sampled values point to radians for 6 of 6" in unit_line(text)
    assert "init: the config validates" in err


def test_one_joint_in_other_units_gets_its_own_entry(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    values = DEGREES.copy()
    values[:, WRIST_ROLL] = np.radians(values[:, WRIST_ROLL])  # wrist_roll logged in radians, the others in degrees
    data, text, err = init(run_cli, examples_dir, tmp_path, values)
    joints = joints_of(data)
    assert joints["unit"] == "deg" and joints["map"]["wrist_roll"] == {"joint": "wrist_roll", "unit": "rad"}
    assert "sampled values point to degrees for 5 of 6" in unit_line(text)
    assert "init: the config validates" in err


def test_a_sample_that_does_not_fit_is_never_said_to_validate(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    values = DEGREES.copy()
    values[:, GRIPPER] = -values[:, GRIPPER]  # the gripper logged negated: -85..-5 deg for limits -10..100 deg
    data, text, err = init(run_cli, examples_dir, tmp_path, values)
    assert joints_of(data)["unit"] == "deg"
    assert "the config validates" not in err
    assert "validate accepts it, but 1 mapped value(s) of the sample (300 rows) do not fit their URDF limits as written" in err
    (line,) = [line for line in err.splitlines() if line.startswith("  gripper -> gripper [deg]: values")]
    assert "outside the limits" in line and "negate" in line
    assert "fit the limits in degrees only with another correction: see check" in text


def test_values_that_fit_no_unit_keep_the_urdfs_and_say_so(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    values = DEGREES.copy()
    values[:, SHOULDER_PAN] = np.linspace(-5000, 5000, len(values))  # no unit and no correction puts these in +-110 deg
    data, text, err = init(run_cli, examples_dir, tmp_path, values)
    assert "fit the limits in no unit as they are: see check" in text
    assert "the config validates" not in err and "probably another joint" in err


def test_printed_config_says_its_paths_are_relative_to_the_current_folder(
    run_cli, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    printed = run_cli("init", "--urdf", str(examples_dir / SO101))
    assert printed.code == 0 and printed.out.startswith("# yaml-language-server:")
    assert f"init: the paths in the printed config are relative to the current folder ({tmp_path})" in printed.err
    written = run_cli("init", "--urdf", str(examples_dir / SO101), "-o", str(tmp_path / "x.yaml"))
    assert written.code == 0 and "relative to the current folder" not in written.err


def test_the_unit_choice_is_check_s_rule(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    """Values near zero fit deg and rad alike and reach too little of the range to tell: the URDF's rad is kept, and
    the comment says to settle it."""
    values = np.radians(DEGREES) * 0.05  # a few degrees of motion, in radians
    values[:, GRIPPER] = math.radians(20)  # the gripper still, within its -10..100 deg
    data, text, _ = init(run_cli, examples_dir, tmp_path, values)
    assert joints_of(data)["unit"] == "rad" and "fit the limits in rad and deg: rad (settle against a known pose)" in text

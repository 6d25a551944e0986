"""`urdf-pipeline init` with every URDF form `run` accepts (--xacro with --arg, --robot-descriptions), expanded by the
same code, written in the matching form; and a positional source whose width is not the URDF's joints to drive."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import rtbdata
import yaml

from urdf_pipeline.compile.compiler import compile_config
from urdf_pipeline.examples import write_joint_parquet, write_lerobot_dataset
from urdf_pipeline.scaffold.init_urdf import parse_xacro_args
from urdf_pipeline.urdf.model import read_urdf

from ..urdf.test_urdf_sources import SO101_JOINTS, offline_git, so101_description_cache  # noqa: F401 (a fixture)

RTB_XACRO = Path(rtbdata.__file__).parent / "xacro"
VX300S = RTB_XACRO / "trossen_descriptions" / "urdf" / "vx300s.urdf.xacro"
VX300S_JOINTS = ["waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate", "gripper", "left_finger"]
MACRO = """<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="arm" params="prefix">
    <link name="${prefix}base"/>
    <link name="${prefix}upper"><visual><geometry><mesh filename="package://my_arm/meshes/upper.stl"/></geometry></visual></link>
    <joint name="${prefix}shoulder" type="revolute">
      <parent link="${prefix}base"/><child link="${prefix}upper"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/>
    </joint>
  </xacro:macro>
</robot>
"""
ARM = """<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="prefix" default=""/>
  <xacro:include filename="$(find my_arm)/urdf/macro.xacro"/>
  <xacro:arm prefix="$(arg prefix)"/>
</robot>
"""


def only_robot(data: dict) -> dict:
    (robot,) = data["robots"].values()
    return robot


def my_arm(root: Path) -> Path:
    """A ROS-style package my_arm whose xacro includes a macro through $(find my_arm) and takes an argument."""
    package = root / "my_arm"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    shutil.copy(next((RTB_XACRO / "trossen_descriptions" / "meshes").rglob("*.stl")), package / "meshes" / "upper.stl")
    (package / "urdf" / "macro.xacro").write_text(MACRO)
    (package / "urdf" / "arm.urdf.xacro").write_text(ARM)
    return package / "urdf" / "arm.urdf.xacro"


def test_xacro_with_args_from_rtb_data_is_written_in_the_xacro_form_and_validates(tmp_path: Path, run_cli) -> None:
    config = tmp_path / "vx300s.yaml"
    result = run_cli("init", "--xacro", str(VX300S), "--arg", "robot_name=vx300s", "-o", str(config))
    assert result.code == 0, result.err
    data = yaml.safe_load(config.read_text())
    robot = only_robot(data)
    assert set(robot["urdf"]) == {"xacro", "args"} and robot["urdf"]["args"] == {"robot_name": "vx300s"}
    assert (config.parent / robot["urdf"]["xacro"]).resolve() == VX300S.resolve()
    assert (config.parent / robot["package_paths"]["trossen_descriptions"]).resolve() == (RTB_XACRO / "trossen_descriptions").resolve()
    assert list(robot["joints"]["map"]) == VX300S_JOINTS
    assert data["edges"][0]["child"] == "vx300s/base_link"  # the argument reached xacro
    assert f"from xacro {robot['urdf']['xacro']} robot_name:=vx300s" in config.read_text()
    (source,) = data["sources"].values()
    write_joint_parquet(config.parent / source["parquet"], np.zeros((3, len(VX300S_JOINTS))))
    plan = compile_config(config)
    assert plan.robots[0].urdf_origin.endswith("vx300s.urdf.xacro robot_name:=vx300s")


def test_xacro_find_is_found_beside_it_and_paths_are_relative(tmp_path: Path, run_cli) -> None:
    xacro = my_arm(tmp_path / "configs" / "robots")
    config = tmp_path / "configs" / "arm.yaml"
    result = run_cli("init", "--xacro", str(xacro), "--arg", "prefix=left_", "-o", str(config))
    assert result.code == 0, result.err
    robot = only_robot(yaml.safe_load(config.read_text()))
    assert robot["urdf"] == {"xacro": "robots/my_arm/urdf/arm.urdf.xacro", "args": {"prefix": "left_"}}
    assert robot["package_paths"] == {"my_arm": "robots/my_arm"}  # for $(find my_arm) and package://my_arm meshes
    assert "$(find my_arm) in the xacro" in config.read_text()
    assert list(robot["joints"]["map"]) == ["left_shoulder"]
    assert "file not found" in result.err and result.err.count("\n  ") == 1  # only the stub source is refused
    write_joint_parquet(config.parent / "TODO" / "arm.parquet", np.zeros((3, 1)))
    assert run_cli("validate", str(config)).code == 0


def test_xacro_problems_are_the_options(tmp_path: Path, run_cli) -> None:
    xacro = my_arm(tmp_path / "robots")
    (tmp_path / "robots" / "my_arm").rename(tmp_path / "robots" / "renamed")  # $(find my_arm) has nothing to find
    moved = tmp_path / "robots" / "renamed" / "urdf" / "arm.urdf.xacro"
    result = run_cli("init", "--xacro", str(moved), "-o", str(tmp_path / "c.yaml"))
    assert result.code == 1 and result.err.startswith(f"error: --xacro {moved}: the xacro needs $(find my_arm)")
    assert "ROS_PACKAGE_PATH" in result.err and not (tmp_path / "c.yaml").exists()
    assert "xacro file not found" in run_cli("init", "--xacro", str(xacro)).err
    (tmp_path / "bad.urdf.xacro").write_text('<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="$(arg p)"/></robot>')
    result = run_cli("init", "--xacro", str(tmp_path / "bad.urdf.xacro"))
    assert result.code == 1 and "xacro argument 'p' has no value" in result.err


def test_xacro_outside_the_output_folder_is_expanded_and_the_refusal_said(tmp_path: Path, run_cli) -> None:
    xacro = my_arm(tmp_path / "robots")
    result = run_cli("init", "--xacro", str(xacro), "-o", str(tmp_path / "elsewhere" / "arm.yaml"))
    assert result.code == 0, result.err
    assert "outside the config's folder" in result.err and "the config validates" not in result.err


def test_usage_errors(tmp_path: Path, run_cli) -> None:
    urdf = str(tmp_path / "r.urdf")
    assert run_cli("init").code == 2  # one form is required
    assert run_cli("init", "--urdf", urdf, "--xacro", str(VX300S)).code == 2  # only one
    assert run_cli("init", "--urdf", urdf, "--robot-descriptions", "x").code == 2
    result = run_cli("init", "--urdf", urdf, "--arg", "a=b")
    assert result.code == 2 and "--arg NAME=VALUE goes with --xacro" in result.err
    result = run_cli("init", "--xacro", str(VX300S), "--arg", "robot_name")
    assert result.code == 2 and "NAME=VALUE" in result.err
    assert run_cli("init", "--xacro", str(VX300S), "--arg", "=x").code == 2
    assert "given twice" in run_cli("init", "--xacro", str(VX300S), "--arg", "a=1", "--arg", "a=2").err
    assert parse_xacro_args(["a=b=c", "empty="]) == (("a", "b=c"), ("empty", ""))  # split at the first `=`


@pytest.mark.usefixtures("offline_git")
def test_robot_descriptions_from_a_local_cache(tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch, erd_share: Path) -> None:
    commit = so101_description_cache(tmp_path, monkeypatch, erd_share)
    config = tmp_path / "configs" / "so101.yaml"
    result = run_cli("init", "--robot-descriptions", "so_arm101_description", "-o", str(config))
    assert result.code == 0, result.err
    data = yaml.safe_load(config.read_text())
    robot = only_robot(data)
    assert robot["urdf"] == {"robot_descriptions": "so_arm101_description"} and "package_paths" not in robot
    assert sorted(robot["joints"]["map"]) == sorted(SO101_JOINTS)
    assert "from robot_descriptions so_arm101_description" in config.read_text()
    write_joint_parquet(config.parent / data["sources"]["so101_new_calib_state"]["parquet"], np.zeros((3, 6)))
    assert compile_config(config).robots[0].urdf_origin.startswith(f"robot_descriptions so_arm101_description @ {commit}")


@pytest.mark.usefixtures("offline_git")
def test_robot_descriptions_offline_or_misspelt_names_the_option(tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROBOT_DESCRIPTIONS_CACHE", str(tmp_path / "empty-cache"))
    monkeypatch.delenv("ROBOT_DESCRIPTION_COMMIT", raising=False)
    result = run_cli("init", "--robot-descriptions", "so_arm101_description")
    assert result.code == 1 and "error: --robot-descriptions so_arm101_description: " in result.err
    assert "no cached copy" in result.err and "Traceback" not in result.err
    result = run_cli("init", "--robot-descriptions", "so_arm101_descriptoin")
    assert result.code == 1 and "did you mean so_arm101_description" in result.err


def drivable(urdf: Path) -> list[str]:
    _, model = read_urdf(urdf)
    return [j.name for j in model.joints if j.moving and j.mimic is None]


def test_a_parquet_wider_than_the_joints_is_a_problem_not_validated(erd_share: Path, tmp_path: Path, run_cli) -> None:
    urdf = erd_share / "robots" / "z1_description" / "urdf" / "z1.urdf"
    joints = drivable(urdf)
    assert len(joints) == 7
    write_joint_parquet(tmp_path / "wide.parquet", np.zeros((4, 9)))
    config = tmp_path / "z1.yaml"
    result = run_cli("init", "--urdf", str(urdf), "--source", f"parquet:{tmp_path / 'wide.parquet'}", "-o", str(config))
    assert result.code == 0, result.err
    assert "the config validates" not in result.err
    assert "sources.z1_description_state: 9 values per row, but URDF 'z1_description' has 7 joints to drive" in result.err
    assert "ignores the other 2 (value_7 .. value_8)" in result.err
    assert "edit sources.z1_description_state.names" in result.err
    text = config.read_text()
    assert "its 9 values are not one per URDF joint" in [line for line in text.splitlines() if "names:" in line][0]
    assert run_cli("validate", str(config)).code == 0  # valid as written: only init knows the guess is wrong


def test_a_lerobot_feature_without_names_narrower_than_the_joints(erd_share: Path, tmp_path: Path, run_cli) -> None:
    urdf = erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf"
    write_lerobot_dataset(tmp_path / "ds", np.zeros((5, 5)), None)  # type: ignore[arg-type]
    info = json.loads((tmp_path / "ds" / "meta" / "info.json").read_text())
    assert info["features"]["observation.state"]["names"] is None
    result = run_cli("init", "--urdf", str(urdf), "--source", f"lerobot:{tmp_path / 'ds'}", "-o", str(tmp_path / "so101.yaml"))
    assert result.code == 0, result.err
    assert "the config validates" not in result.err
    assert "5 values per row, but URDF 'so101_new_calib' has 6 joints to drive" in result.err
    assert f"holds the other 1 ({drivable(urdf)[-1]})" in result.err


def test_equal_width_still_validates(erd_share: Path, tmp_path: Path, run_cli) -> None:
    urdf = erd_share / "robots" / "z1_description" / "urdf" / "z1.urdf"
    write_joint_parquet(tmp_path / "seven.parquet", np.zeros((4, 7)))
    result = run_cli("init", "--urdf", str(urdf), "--source", f"parquet:{tmp_path / 'seven.parquet'}", "-o", str(tmp_path / "z1.yaml"))
    assert result.code == 0 and "init: the config validates" in result.err and "values per row" not in result.err

"""URDF forms: plain, xacro with args and $(find), robot_descriptions from a local cache; provenance in the .rrd."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rtbdata
import yaml
from rerun.chunk import RrdReader

from urdf_pipeline.examples import write_joint_parquet

from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames, rotation_angle

RTB_XACRO = Path(rtbdata.__file__).parent / "xacro"
VX300S_ARM = ["waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate"]


def write_config(directory: Path, name: str, robot: dict, names: list[str], parquet: str) -> Path:
    config = {
        "version": 1,
        "sources": {"state": {"parquet": parquet, "column": "observation.state", "index": "frame_index", "names": names}},
        "robots": {"arm": robot},
        "output": {"path": "out/{segment}.rrd", "application_id": name, "segment": name},
    }
    path = directory / f"{name}.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


def vx300s_robot(**urdf_extra) -> dict:
    return {
        "urdf": {
            "xacro": str(RTB_XACRO / "trossen_descriptions" / "urdf" / "vx300s.urdf.xacro"),
            "args": {"robot_name": "vx300s"},
            **urdf_extra,
        },
        "package_paths": {"trossen_descriptions": str(RTB_XACRO / "trossen_descriptions")},
        "joints": {
            "source": "state",
            "map": {**{j: j for j in VX300S_ARM}, "gripper": "gripper", "finger": {"joint": "left_finger", "unit": "m"}},
        },
    }


def properties(rrd: Path) -> dict:
    for chunk in RrdReader(rrd).stream().to_chunks():
        if chunk.entity_path == "/__properties/urdf_pipeline":
            row = chunk.to_record_batch().to_pylist()[0]
            return {k: v[0] for k, v in row.items() if k != "rerun.controls.RowId"}
    raise AssertionError("no provenance properties in the recording")


def test_xacro_with_args_runs_and_matches_pinocchio(tmp_path: Path, run_cli) -> None:
    names = [*VX300S_ARM, "gripper", "finger"]
    expanded = tmp_path / "vx300s.urdf"
    result = run_cli("run", str(write_config(tmp_path, "vx300s", vx300s_robot(), names, "data.parquet")))  # no data yet: a user error
    assert result.code == 1 and "file not found" in result.err
    # pinocchio needs a plain URDF: expand it independently, with the xacro package's own command line entry point
    xacro_file = RTB_XACRO / "trossen_descriptions" / "urdf" / "vx300s.urdf.xacro"
    command = f"import sys, xacro; sys.argv = ['xacro', {str(xacro_file)!r}, 'robot_name:=vx300s', '-o', {str(expanded)!r}]; xacro.main()"
    subprocess.run([sys.executable, "-c", command], check=True, capture_output=True)
    reference = PinocchioRobot(expanded)
    rng = np.random.default_rng(5)
    bounds = np.array([reference.limits(j) for j in [*VX300S_ARM, "left_finger"]])
    q = rng.uniform(bounds[:, 0], bounds[:, 1], size=(20, 7))
    gripper = rng.uniform(-3, 3, size=(20, 1))
    write_joint_parquet(tmp_path / "data.parquet", np.concatenate([q[:, :6], gripper, q[:, 6:]], axis=1))
    result = run_cli("run", str(tmp_path / "vx300s.yaml"))
    assert result.code == 0, result.err
    assert "from xacro" in result.err and "robot_name:=vx300s" in result.err
    rrd = Path(result.out.strip())
    props = properties(rrd)
    assert props["arm_urdf_origin"].endswith("vx300s.urdf.xacro robot_name:=vx300s")
    assert len(props["arm_urdf_sha256"]) == 64
    frames = read_frames(rrd, "frame_index")
    for frame in (0, 19):
        values = dict(zip(VX300S_ARM, q[frame, :6], strict=True))
        values.update(gripper=gripper[frame, 0], left_finger=q[frame, 6], right_finger=-q[frame, 6])  # right_finger mimics -1x
        for link, expected in reference.link_poses(values).items():
            recorded = frames.world_pose(link, frame, "vx300s/base_link")
            assert np.linalg.norm(recorded[:3, 3] - expected[:3, 3]) < 1e-5, link
            assert rotation_angle(recorded, expected) < 1e-5, link


def test_xacro_find_is_answered_from_package_paths(tmp_path: Path, run_cli) -> None:
    package = RTB_XACRO / "qut_frankie_description"
    robot = {
        "urdf": {"xacro": str(package / "robots" / "frankie_arm.urdf.xacro")},
        "package_paths": {},
        "allow_missing_meshes": True,
        "joints": {"source": "state", "map": {"j": "panda_joint1"}},
    }
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((3, 1)))
    result = run_cli("validate", str(write_config(tmp_path, "frankie", robot, ["j"], "d.parquet")))
    assert result.code == 1 and "xacro needs $(find qut_frankie_description)" in result.err and "package_paths" in result.err
    robot["package_paths"] = {"qut_frankie_description": str(package)}
    result = run_cli("validate", str(write_config(tmp_path, "frankie", robot, ["j"], "d.parquet")))
    assert "$(find" not in result.err
    assert "URDF joints not driven by any source value: panda_base_joint1, panda_base_joint2" in result.err  # it expanded


def test_missing_xacro_argument_is_named(tmp_path: Path, run_cli) -> None:
    (tmp_path / "r.urdf.xacro").write_text(
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="$(arg prefix)base"/></robot>'
    )
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((3, 1)))
    robot = {"urdf": {"xacro": "r.urdf.xacro"}, "joints": {"source": "state", "map": {}, "ignore": ["j"]}}
    robot["joints"]["map"] = {"j": "x"}
    result = run_cli("validate", str(write_config(tmp_path, "r", robot, ["j"], "d.parquet")))
    assert result.code == 1 and "xacro argument 'prefix' has no value" in result.err


def test_xacro_given_as_plain_urdf_says_to_use_the_xacro_form(tmp_path: Path, run_cli) -> None:
    (tmp_path / "r.urdf.xacro").write_text("<robot name='r'/>")
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((3, 1)))
    robot = {"urdf": "r.urdf.xacro", "joints": {"source": "state", "map": {"j": "x"}}}
    result = run_cli("validate", str(write_config(tmp_path, "r", robot, ["j"], "d.parquet")))
    assert result.code == 1 and "use the xacro form: urdf: {xacro: r.urdf.xacro" in result.err


def _so101_repository(root: Path, erd_share: Path) -> str:
    """A git repository shaped like TheRobotStudio/SO-ARM100 (Simulation/SO101), committed; returns the commit."""
    package = root / "Simulation" / "SO101"
    (package / "assets").mkdir(parents=True)
    source = erd_share / "robots" / "so_arm_description"
    text = (source / "urdf" / "so101.urdf").read_text()
    for mesh in (source / "meshes" / "so101").glob("*.stl"):
        shutil.copy(mesh, package / "assets" / mesh.name)
    text = text.replace("package://example-robot-data/robots/so_arm_description/meshes/so101/", "assets/")
    (package / "so101_new_calib.urdf").write_text(text)
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "init.defaultBranch=main"]
    subprocess.run([*git, "init", "-q", str(root)], check=True)
    subprocess.run([*git, "-C", str(root), "add", "-A"], check=True)
    subprocess.run([*git, "-C", str(root), "commit", "-q", "-m", "so101"], check=True)
    return subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture
def offline_git(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Any fetch from GitHub fails at once: no network is used even by accident."""
    config = tmp_path / "gitconfig"
    config.write_text('[url "file:///nonexistent-offline/"]\n\tinsteadOf = https://github.com/\n')
    monkeypatch.setenv("GIT_CONFIG_GLOBAL", str(config))


SO101_JOINTS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def so101_robot() -> dict:
    return {"urdf": {"robot_descriptions": "so_arm101_description"}, "joints": {"source": "state", "map": {j: j for j in SO101_JOINTS}}}


def so101_description_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, erd_share: Path) -> str:
    """robot_descriptions' so_arm101_description answered from a local cache (no network): its git repository made
    from example-robot-data's SO-101 files, at the commit the environment names."""
    cache = tmp_path / "cache"
    staging = tmp_path / "staging" / "SO-ARM100"
    commit = _so101_repository(staging, erd_share)
    shutil.move(str(staging), str(cache / f"SO-ARM100-{commit}" / "SO-ARM100"))
    monkeypatch.setenv("ROBOT_DESCRIPTIONS_CACHE", str(cache))
    monkeypatch.setenv("ROBOT_DESCRIPTION_COMMIT", commit)
    return commit


def test_robot_descriptions_from_a_local_cache(tmp_path: Path, run_cli, monkeypatch, offline_git, erd_share: Path) -> None:
    commit = so101_description_cache(tmp_path, monkeypatch, erd_share)
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((5, 6)))
    result = run_cli("run", str(write_config(tmp_path, "so101_rd", so101_robot(), SO101_JOINTS, "d.parquet")))
    assert result.code == 0, result.err
    origin = properties(Path(result.out.strip()))["arm_urdf_origin"]
    assert origin == f"robot_descriptions so_arm101_description @ {commit}: Simulation/SO101/so101_new_calib.urdf"


def test_robot_descriptions_offline_without_cache_names_the_cache(tmp_path: Path, run_cli, monkeypatch, offline_git) -> None:
    monkeypatch.setenv("ROBOT_DESCRIPTIONS_CACHE", str(tmp_path / "empty-cache"))
    monkeypatch.delenv("ROBOT_DESCRIPTION_COMMIT", raising=False)
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((5, 6)))
    result = run_cli("validate", str(write_config(tmp_path, "so101_off", so101_robot(), SO101_JOINTS, "d.parquet")))
    assert result.code == 1
    assert "ROBOT_DESCRIPTIONS_CACHE=" in result.err and "no cached copy" in result.err and "Traceback" not in result.err


def test_unknown_robot_description_suggests_names(tmp_path: Path, run_cli) -> None:
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((5, 6)))
    robot = {**so101_robot(), "urdf": {"robot_descriptions": "so_arm101_descriptoin"}}
    result = run_cli("validate", str(write_config(tmp_path, "so101_typo", robot, SO101_JOINTS, "d.parquet")))
    assert result.code == 1 and "did you mean so_arm101_description" in result.err


def test_xacro_file_outside_the_config_folder_is_refused(tmp_path: Path, run_cli) -> None:
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "r.urdf.xacro").write_text("<robot name='r'><link name='base'/></robot>")
    (tmp_path / "pr").mkdir()
    write_joint_parquet(tmp_path / "pr" / "d.parquet", np.zeros((3, 1)))
    robot = {"urdf": {"xacro": "../outside/r.urdf.xacro"}, "joints": {"source": "state", "map": {"j": "x"}}}
    config = write_config(tmp_path / "pr", "r", robot, ["j"], "d.parquet")
    result = run_cli("validate", str(config))
    assert result.code == 1 and f"error: {config}:" in result.err
    assert f"xacro file {tmp_path / 'outside' / 'r.urdf.xacro'} is outside the config's folder" in result.err


def test_xacro_warnings_reach_stderr_and_the_expansion_is_used(tmp_path: Path, run_cli) -> None:
    (tmp_path / "r.urdf.xacro").write_text(
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:property name="pi" value="3"/>'
        '<link name="base"/><link name="l1"/><joint name="j_${pi}" type="revolute"><parent link="base"/><child link="l1"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>'
    )
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((3, 1)))
    robot = {"urdf": {"xacro": "r.urdf.xacro"}, "joints": {"source": "state", "map": {"j": "j_3"}}}
    result = run_cli("validate", str(write_config(tmp_path, "r", robot, ["j"], "d.parquet")))
    assert result.code == 0, result.err  # the expanded URDF names its joint j_3
    assert "warning: redefining global symbol: pi" in result.err  # xacro's own warning, from the child process

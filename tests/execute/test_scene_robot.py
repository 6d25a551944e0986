"""A scene URDF (a table with a camera mount) needs no joint source; a moving URDF without `joints` is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from ..rrd_frames import read_frames

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

SCENE = """<?xml version="1.0"?>
<robot name="scene">
  <link name="table"><visual><geometry><box size="1.2 0.8 0.05"/></geometry></visual></link>
  <link name="camera_mount"/>
  <joint name="mount" type="fixed"><parent link="table"/><child link="camera_mount"/><origin xyz="0.5 0 0.6" rpy="0 0.5 3.14159"/></joint>
</robot>
"""


def scene_config(examples_dir: Path, tmp_path: Path, scene: dict) -> Path:
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    arm = data["robots"]["arm"]
    arm["urdf"] = str(examples_dir / arm["urdf"])
    arm["package_paths"] = {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")}
    data["sources"]["arm_state"]["parquet"] = str(examples_dir / "data" / "episode_000.parquet")
    data["robots"]["scene"] = scene
    data["edges"].append({"parent": "world", "child": "scene_table", "translation": [0.3, 0.0, 0.45], "quaternion_xyzw": [0, 0, 0, 1]})
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_scene_without_joints_is_placed_by_its_static_transforms(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    (tmp_path / "scene.urdf").write_text(SCENE)
    config = scene_config(examples_dir, tmp_path, {"urdf": "scene.urdf", "frame_prefix": "scene_"})
    plan = run_cli("plan", str(config))
    assert plan.code == 0, plan.err
    assert "a scene: no moving joints" in plan.out
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    mount = frames.world_pose("scene_camera_mount", 0, "world")
    assert np.allclose(mount[:3, 3], [0.8, 0.0, 1.05], atol=1e-6)
    assert frames.static_entities["scene_camera_mount"] == "/scene/tf_static"


def test_moving_urdf_without_joints_is_refused(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    config = scene_config(examples_dir, tmp_path, {"urdf": str(examples_dir / "robots" / "panda.urdf"), "frame_prefix": "scene_"})
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "has moving joints (panda_joint1" in result.err and "add joints:" in result.err

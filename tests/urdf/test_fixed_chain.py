"""fixed_chain edges: the pose composed across a URDF's fixed joints equals pinocchio's relative placement."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf.fixed_chain import NoFixedChain, compose_chain, find_fixed_chain
from urdf_pipeline.urdf.model import parse_urdf_text

from ..edge_helpers import RIG_URDF, matrix, panda_config, random_panda_parquet, rig_config, write_config, write_rig
from ..execute.test_fk_against_pinocchio import assert_poses_match, panda_joint_values
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames

RIG = parse_urdf_text(RIG_URDF, "rig.urdf")


def relative_placement(reference: PinocchioRobot, joint_values: dict[str, float], start: str, end: str) -> np.ndarray:
    poses = reference.link_poses(joint_values)
    return np.linalg.inv(poses[start]) @ poses[end]


@pytest.mark.parametrize(
    ("start", "end", "joints"),
    [
        ("flange", "cam", ("flange_to_adapter", "adapter_to_cam")),
        ("arm", "cam", ("arm_to_flange", "flange_to_adapter", "adapter_to_cam")),
        ("base", "bracket", ("base_to_mount", "mount_to_bracket")),
        ("flange", "tool", ("flange_to_tool",)),
        ("base", "base", ()),
    ],
)
def test_composition_equals_pinocchio_placement(start: str, end: str, joints: tuple[str, ...], tmp_path: Path) -> None:
    found = find_fixed_chain(RIG, start, end)
    assert tuple(j.name for j in found) == joints
    translation, quaternion = compose_chain(found)
    reference = PinocchioRobot(write_rig(tmp_path))
    # Fixed joints do not move: any value of the revolute joint gives the same relative placement.
    for shoulder in (0.0, 1.3):
        assert_poses_match(
            matrix(translation, quaternion), relative_placement(reference, {"shoulder": shoulder}, start, end), f"{start}->{end}"
        )


@pytest.mark.parametrize(
    ("start", "end", "stuck", "blocking", "above"),
    [
        ("base", "cam", "bracket", "shoulder", False),  # the deepest link toward cam that fixed joints reach
        ("mount", "arm", "bracket", "shoulder", False),
        ("mount", "lidar", "mount", None, False),  # lidar hangs off base, beside mount: not below it
        ("cam", "flange", "cam", None, True),  # flange is above cam: from and to swapped
    ],
)
def test_walk_reports_where_it_is_stuck(start: str, end: str, stuck: str, blocking: str | None, above: bool) -> None:
    with pytest.raises(NoFixedChain) as error:
        find_fixed_chain(RIG, start, end)
    assert error.value.stuck == stuck
    assert (error.value.blocking.name if error.value.blocking else None) == blocking
    assert error.value.end_is_above is above


def test_rig_fixed_chains_in_the_recording_match_pinocchio(examples_dir: Path, run_cli) -> None:
    """Prefixed frames; edges whose parent is `from` (so the child sits on `to`) and one hung elsewhere."""
    reference = PinocchioRobot(write_rig(examples_dir))
    rng = np.random.default_rng(21)
    q = rng.uniform(-2.0, 2.0, size=(20, 1))
    write_joint_parquet(examples_dir / "data" / "rig_fixed_chain.parquet", q)
    edges = [
        {"parent": "world", "child": "rig_base", "translation": [0.3, -0.1, 0.8], "rpy": [0.2, -0.3, 0.9]},
        {"parent": "rig_flange", "child": "cam_copy", "fixed_chain": {"from": "rig_flange", "to": "rig_cam"}},
        {"parent": "rig_arm", "child": "cam_from_arm", "fixed_chain": {"from": "rig_arm", "to": "rig_cam"}},
        {"parent": "rig_base", "child": "bracket_copy", "fixed_chain": {"from": "rig_base", "to": "rig_bracket"}},
        {"parent": "world", "child": "mount_to_bracket", "fixed_chain": {"from": "rig_mount", "to": "rig_bracket"}},
    ]
    config = write_config(examples_dir, "fixed_chain_rig", rig_config("fixed_chain_rig", "data/rig_fixed_chain.parquet", edges, "rig_"))
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    for child in ("cam_copy", "cam_from_arm", "bracket_copy", "mount_to_bracket"):
        assert frames.static_entities[child] == "/calibration"
    world_from_base = np.eye(4)
    world_from_base[:3, :3] = pin.rpy.rpyToMatrix(0.2, -0.3, 0.9)
    world_from_base[:3, 3] = [0.3, -0.1, 0.8]
    for frame in (0, 7, 19):
        poses = reference.link_poses({"shoulder": float(q[frame, 0])})
        for child, link in (("cam_copy", "cam"), ("cam_from_arm", "cam"), ("bracket_copy", "bracket")):
            recorded = frames.world_pose(child, frame, "world")
            assert_poses_match(recorded, world_from_base @ poses[link], f"{child} at frame {frame}")
        recorded = frames.world_pose("mount_to_bracket", frame, "world")
        assert_poses_match(recorded, np.linalg.inv(poses["mount"]) @ poses["bracket"], "mount_to_bracket")


def test_panda_hand_tcp_chain_matches_pinocchio(examples_dir: Path, run_cli) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    parquet, q = random_panda_parquet(examples_dir, "fixed_chain_panda", reference, frames=16, seed=22)
    edges = [
        {"parent": "world", "child": "panda_link0", "translation": [0.0, 0.0, 0.5], "quaternion_xyzw": [0, 0, 0, 1]},
        {"parent": "panda_link7", "child": "wrist_cam", "fixed_chain": {"from": "panda_link7", "to": "panda_hand_tcp"}},
    ]
    config = write_config(examples_dir, "fixed_chain_panda", panda_config(examples_dir, "fixed_chain_panda", parquet, edges))
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    world_from_base = np.eye(4)
    world_from_base[:3, 3] = [0.0, 0.0, 0.5]
    for frame in (0, 5, 15):
        expected = world_from_base @ reference.link_poses(panda_joint_values(q[frame]))["panda_hand_tcp"]
        assert_poses_match(frames.world_pose("wrist_cam", frame, "world"), expected, f"wrist_cam at frame {frame}")

    plan = run_cli("plan", str(config))
    assert plan.code == 0, plan.err
    assert "edge panda_link7 -> wrist_cam: fixed chain panda_link7 -> panda_hand_tcp of robot arm" in plan.out
    assert "fixed joints composed: panda_joint8, panda_hand_joint, panda_hand_tcp_joint" in plan.out


def test_fixed_chain_across_robots_is_refused(examples_dir: Path, run_cli) -> None:
    data = yaml.safe_load((examples_dir / "bimanual_pandas.yaml").read_text())
    data["edges"].append(
        {"parent": "left_panda_hand", "child": "cam", "fixed_chain": {"from": "left_panda_hand", "to": "right_panda_hand_tcp"}}
    )
    data["output"]["segment"] = "fixed_chain_across"
    config = write_config(examples_dir, "fixed_chain_across", data)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert (
        "no fixed chain from left_panda_hand to right_panda_hand_tcp; stuck at left_panda_hand: "
        "'right_panda_hand_tcp' is a link of robot 'right', 'left_panda_hand' of robot 'left'" in result.err
    )

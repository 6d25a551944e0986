"""Correctness: link poses composed from the written .rrd equal pinocchio's forward kinematics.

Joint values are random within limits; the conversion from raw source values to radians is re-derived
here from the config's documented meaning, not taken from the package.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from urdf_pipeline.examples import write_joint_parquet, write_lerobot_dataset

from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames, rotation_angle

TOLERANCE_M = 1e-5
TOLERANCE_RAD = 1e-5
PANDA_ARM = [f"panda_joint{i}" for i in range(1, 8)]
SO101_JOINTS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def random_within_limits(robot: PinocchioRobot, joints: list[str], frames: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    bounds = np.array([robot.limits(j) for j in joints])
    return rng.uniform(bounds[:, 0], bounds[:, 1], size=(frames, len(joints)))


def panda_contract_raw(q: np.ndarray) -> np.ndarray:
    """Inverse of the contract config: degrees, j2 sign -1, j3 offset 0.1 rad, finger in mm."""
    raw = np.degrees(q[:, :7])
    raw[:, 1] = np.degrees(-q[:, 1])
    raw[:, 2] = np.degrees(q[:, 2] - 0.1)
    return np.concatenate([raw, q[:, 7:8] * 1000.0], axis=1)


def panda_joint_values(q_row: np.ndarray) -> dict[str, float]:
    values = dict(zip(PANDA_ARM, q_row[:7], strict=False))
    values["panda_finger_joint1"] = q_row[7]
    values["panda_finger_joint2"] = q_row[7]  # <mimic joint="panda_finger_joint1"/>, multiplier 1, offset 0
    return values


def variant(examples_dir: Path, config: str, name: str, edit) -> Path:
    data = yaml.safe_load((examples_dir / config).read_text())
    edit(data)
    data["output"]["segment"] = name
    path = examples_dir / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def assert_poses_match(recorded_pose: np.ndarray, expected: np.ndarray, label: str) -> None:
    position_error = float(np.linalg.norm(recorded_pose[:3, 3] - expected[:3, 3]))
    angle_error = rotation_angle(recorded_pose, expected)
    assert position_error < TOLERANCE_M, f"{label}: position off by {position_error:.3g} m"
    assert angle_error < TOLERANCE_RAD, f"{label}: rotation off by {angle_error:.3g} rad"


def check_robot(
    frames, times, reference: PinocchioRobot, values_per_frame, prefix: str, world_from_root: np.ndarray, root: str, checked_frames
) -> int:
    compared = 0
    for frame in checked_frames:
        expected_links = reference.link_poses(values_per_frame[frame])
        for link, link_pose in expected_links.items():
            recorded = frames.world_pose(prefix + link, times[frame], root)
            assert_poses_match(recorded, world_from_root @ link_pose, f"{prefix}{link} at frame {frame}")
            compared += 1
    return compared


def test_panda_contract_config_matches_pinocchio(examples_dir: Path, run_cli) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=64, seed=11)
    write_joint_parquet(examples_dir / "data" / "random_panda.parquet", panda_contract_raw(q))
    config = variant(examples_dir, "demo.yaml", "fk_panda", lambda d: d["sources"]["arm_state"].update(parquet="data/random_panda.parquet"))
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    world_from_base = np.eye(4)
    world_from_base[:3, 3] = [0.0, 0.0, 0.5]  # the contract's calibration edge
    compared = check_robot(
        frames, list(range(64)), reference, [panda_joint_values(row) for row in q], "", world_from_base, "world", [0, 1, 31, 63]
    )
    assert compared == 4 * 13


def test_so101_lerobot_matches_pinocchio(examples_dir: Path, run_cli, erd_share: Path) -> None:
    urdf = erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf"
    reference = PinocchioRobot(urdf)
    q = random_within_limits(reference, SO101_JOINTS, frames=40, seed=12)
    write_lerobot_dataset(examples_dir / "data" / "random_so101", np.degrees(q), SO101_JOINTS)
    config = variant(examples_dir, "so101_lerobot.yaml", "fk_so101", lambda d: d["sources"]["so101"].update(lerobot="data/random_so101"))
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    root = reference.model.frames[1].name  # the URDF root link: with one robot and no frames.root, it is the root
    values = [dict(zip(SO101_JOINTS, row, strict=False)) for row in q]
    assert check_robot(frames, list(range(40)), reference, values, "", np.eye(4), root, [0, 7, 39]) > 0


def random_bimanual_parquet(
    examples_dir: Path, name: str, frames: int, seeds: tuple[int, int]
) -> tuple[PinocchioRobot, np.ndarray, np.ndarray]:
    """data/NAME with two Pandas' random joint values in the contract's units (16 values), and the q of each arm."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    joints = [*PANDA_ARM, "panda_finger_joint1"]
    left = random_within_limits(reference, joints, frames=frames, seed=seeds[0])
    right = random_within_limits(reference, joints, frames=frames, seed=seeds[1])
    write_joint_parquet(examples_dir / "data" / name, np.concatenate([panda_contract_raw(left), panda_contract_raw(right)], axis=1))
    return reference, left, right


def test_bimanual_prefixed_robots_with_rotated_edges_match_pinocchio(examples_dir: Path, run_cli) -> None:
    reference, left, right = random_bimanual_parquet(examples_dir, "random_bimanual.parquet", frames=30, seeds=(13, 14))
    config = variant(
        examples_dir,
        "bimanual_pandas.yaml",
        "fk_bimanual",
        lambda d: d["sources"]["both_arms"].update(parquet="data/random_bimanual.parquet"),
    )
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "timestamp")
    times = sorted({t for by_time in frames.temporal.values() for t in by_time})
    assert len(times) == 30
    for prefix, q, y, yaw in (("left_", left, 0.3, -90.0), ("right_", right, -0.3, 90.0)):
        world_from_base = np.eye(4)
        world_from_base[:3, :3] = pin.rpy.rpyToMatrix(0.0, 0.0, math.radians(yaw))
        world_from_base[:3, 3] = [0.0, y, 0.0]
        check_robot(frames, times, reference, [panda_joint_values(row) for row in q], prefix, world_from_base, "world", [0, 29])


def test_every_static_edge_is_logged_once_and_fixed_joints_are_present(examples_dir: Path, run_cli) -> None:
    result = run_cli("run", str(examples_dir / "demo.yaml"))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    for fixed_child in ("panda_link8", "panda_hand", "panda_hand_tcp"):
        assert frames.static_entities[fixed_child] == "/arm/tf_static"
    assert frames.static_entities["panda_link0"] == "/calibration"
    assert "panda_rightfinger" in frames.temporal, "the mimic finger must be driven by the pipeline"

"""Temporal edges: a pose per row from a source (a mobile base, a floating pelvis), composed from the written .rrd."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.examples import write_joint_parquet

from ..edge_helpers import matrix, panda_config, random_panda_parquet, write_config
from ..execute.test_fk_against_pinocchio import assert_poses_match, panda_contract_raw, panda_joint_values
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames

POSE_NAMES = ["qw", "x", "qx", "y", "qy", "z", "qz"]  # deliberately not in x, y, z, qx, qy, qz, qw order
TEMPORAL_EDGE = {
    "parent": "world",
    "child": "panda_link0",
    "source": "base_pose",
    "translation": ["x", "y", "z"],
    "quaternion_xyzw": ["qx", "qy", "qz", "qw"],
}

FLOATER_URDF = """<?xml version="1.0"?>
<robot name="floater">
  <link name="odom"/><link name="pelvis"/><link name="leg"/><link name="foot"/>
  <joint name="floating_base" type="floating"><parent link="odom"/><child link="pelvis"/></joint>
  <joint name="hip" type="revolute">
    <parent link="pelvis"/><child link="leg"/><origin xyz="0 0.1 -0.1" rpy="0.2 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
  <joint name="ankle" type="fixed"><parent link="leg"/><child link="foot"/><origin xyz="0 0 -0.4" rpy="0 0.3 0"/></joint>
</robot>
"""


def random_poses(frames: int, seed: int) -> np.ndarray:
    """(frames x 7) in POSE_NAMES order; quaternions deliberately not normalised (the pipeline normalises per row)."""
    rng = np.random.default_rng(seed)
    xyz = rng.uniform(-2.0, 2.0, size=(frames, 3))
    quaternion = rng.normal(size=(frames, 4)) * rng.uniform(0.5, 3.0, size=(frames, 1))  # x, y, z, w
    by_name = dict(zip(["x", "y", "z"], xyz.T, strict=True)) | dict(zip(["qx", "qy", "qz", "qw"], quaternion.T, strict=True))
    return np.stack([by_name[name] for name in POSE_NAMES], axis=1).astype(np.float32).astype(np.float64)


def expected_pose(row: np.ndarray) -> np.ndarray:
    value = dict(zip(POSE_NAMES, row, strict=True))
    return matrix([value["x"], value["y"], value["z"]], [value["qx"], value["qy"], value["qz"], value["qw"]])


def base_pose_source(parquet: str, names: list[str] = POSE_NAMES) -> dict:
    return {"parquet": parquet, "column": "pose", "index": "frame_index", "names": names}


def test_moving_base_from_its_own_source_matches_written_values(examples_dir: Path, run_cli) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    joints, q = random_panda_parquet(examples_dir, "temporal_arm", reference, frames=40, seed=31)
    poses = random_poses(40, seed=32)
    write_joint_parquet(examples_dir / "data" / "temporal_base.parquet", poses, column="pose")
    data = panda_config(examples_dir, "temporal_base", joints, [TEMPORAL_EDGE])
    data["sources"]["base_pose"] = base_pose_source("data/temporal_base.parquet")  # used by no robot, only the edge
    config = write_config(examples_dir, "temporal_base", data)

    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    assert "panda_link0" not in frames.static, "the base has only its temporal edge"
    assert sorted(frames.temporal["panda_link0"]) == list(range(40))
    for frame in (0, 1, 17, 39):
        world_from_base = expected_pose(poses[frame])
        assert_poses_match(frames.world_pose("panda_link0", frame, "world"), world_from_base, f"base at frame {frame}")
        for link, link_pose in reference.link_poses(panda_joint_values(q[frame])).items():
            assert_poses_match(frames.world_pose(link, frame, "world"), world_from_base @ link_pose, f"{link} at frame {frame}")


def test_one_source_drives_the_arm_and_its_base(examples_dir: Path, run_cli) -> None:
    """The source is read twice (FK and edge); its pose names are ignored by the robot's joint map."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    _, q = random_panda_parquet(examples_dir, "temporal_shared_arm", reference, frames=25, seed=33)
    poses = random_poses(25, seed=34)
    write_joint_parquet(examples_dir / "data" / "temporal_shared.parquet", np.concatenate([panda_contract_raw(q), poses], axis=1))
    data = panda_config(examples_dir, "temporal_shared", "data/temporal_shared.parquet", [{**TEMPORAL_EDGE, "source": "arm_state"}])
    data["sources"]["arm_state"]["names"] += POSE_NAMES
    data["robots"]["arm"]["joints"]["ignore"] = POSE_NAMES
    config = write_config(examples_dir, "temporal_shared", data)

    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    for frame in (0, 12, 24):
        world_from_base = expected_pose(poses[frame])
        for link, link_pose in reference.link_poses(panda_joint_values(q[frame])).items():
            assert_poses_match(frames.world_pose(link, frame, "world"), world_from_base @ link_pose, f"{link} at frame {frame}")


def test_floating_pelvis_overrides_the_urdf_floating_joint(examples_dir: Path, run_cli) -> None:
    urdf = examples_dir / "robots" / "floater.urdf"
    urdf.write_text(FLOATER_URDF, encoding="utf-8")
    reference = PinocchioRobot(urdf)
    rng = np.random.default_rng(35)
    hip = rng.uniform(-1.5, 1.5, size=(30, 1))
    poses = random_poses(30, seed=36)
    write_joint_parquet(examples_dir / "data" / "floater.parquet", np.concatenate([hip, poses], axis=1).astype(np.float32))
    data = {
        "version": 1,
        "sources": {
            "g": {"parquet": "data/floater.parquet", "column": "observation.state", "index": "frame_index", "names": ["hip", *POSE_NAMES]}
        },
        "robots": {"floater": {"urdf": "robots/floater.urdf", "joints": {"source": "g", "map": {"hip": "hip"}, "ignore": POSE_NAMES}}},
        "edges": [{**TEMPORAL_EDGE, "parent": "odom", "child": "pelvis", "source": "g"}],
        "output": {"path": "out/{segment}.rrd", "application_id": "edge_kinds", "segment": "temporal_floater"},
    }
    config = write_config(examples_dir, "temporal_floater", data)

    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    assert frames.static_entities["pelvis"] == "/floater/tf_static", "the URDF's floating joint keeps its static identity"
    assert set(frames.temporal["pelvis"]) == set(range(30))
    for frame in (0, 9, 29):
        hip_value = float(np.float32(hip[frame, 0]))
        for link, link_pose in reference.link_poses({"hip": hip_value}).items():
            if link == "odom":
                continue  # the root
            expected = expected_pose(poses[frame]) @ link_pose  # pinocchio's free flyer at neutral is the identity
            assert_poses_match(frames.world_pose(link, frame, "odom"), expected, f"{link} at frame {frame}")


def test_zero_quaternion_rows_stop_the_run(examples_dir: Path, run_cli) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    joints, _ = random_panda_parquet(examples_dir, "temporal_zero_arm", reference, frames=20, seed=37)
    poses = random_poses(20, seed=38)
    for name in ("qx", "qy", "qz", "qw"):
        poses[5:8, POSE_NAMES.index(name)] = 0.0
    write_joint_parquet(examples_dir / "data" / "temporal_zero.parquet", poses, column="pose")
    data = panda_config(examples_dir, "temporal_zero", joints, [TEMPORAL_EDGE])
    data["sources"]["base_pose"] = base_pose_source("data/temporal_zero.parquet")
    config = write_config(examples_dir, "temporal_zero", data)

    assert run_cli("validate", str(config)).code == 0, "validate reads no values: it cannot see this"
    result = run_cli("run", str(config))

    assert result.code == 1
    assert (
        "temporal edge world -> panda_link0 (edges[0], source 'base_pose'): 3 of 20 rows have an all-zero quaternion "
        "(qx, qy, qz, qw)" in result.err
    )
    assert f"error: {config}:" in result.err
    assert not (examples_dir / "out" / "temporal_zero.rrd").exists()


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda edge: edge.update(translation=["x", "y", "zz"]), "source 'base_pose' has no value named 'zz'; it has: x, y, z"),
        (lambda edge: edge.update(source="arm_state"), "source 'arm_state' has no value named 'x'"),
    ],
)
def test_value_names_are_checked_before_reading(examples_dir: Path, run_cli, edit, message: str) -> None:
    edge = dict(TEMPORAL_EDGE)
    edit(edge)
    data = panda_config(examples_dir, "temporal_names", "data/episode_000.parquet", [edge])
    data["sources"]["base_pose"] = base_pose_source("data/episode_000.parquet")
    data["sources"]["base_pose"]["column"] = "observation.state"
    data["sources"]["base_pose"]["names"] = ["x", "y", "z", "qx", "qy", "qz", "qw", "spare"]
    if edge["source"] == "arm_state":
        del data["sources"]["base_pose"]
    config = write_config(examples_dir, "temporal_names", data)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert message in result.err


def test_plan_shows_the_temporal_edge(examples_dir: Path, run_cli) -> None:
    poses = random_poses(5, seed=39)
    write_joint_parquet(examples_dir / "data" / "temporal_plan.parquet", poses, column="pose")
    data = panda_config(examples_dir, "temporal_plan", "data/episode_000.parquet", [TEMPORAL_EDGE])
    data["sources"]["base_pose"] = base_pose_source("data/temporal_plan.parquet")
    result = run_cli("plan", str(write_config(examples_dir, "temporal_plan", data)))
    assert result.code == 0, result.err
    assert (
        "temporal edge world -> panda_link0 on /calibration/temporal/panda_link0 (edges[0], line " in result.out
        and "per row of source 'base_pose', translation [x[1], y[3], z[5]], quaternion_xyzw [qx[2], qy[4], qz[6], qw[0]]" in result.out
    )


def test_temporal_edge_from_mcap_maps_pose_values_by_name(examples_dir: Path, run_cli) -> None:
    """Pose values arriving as JointState messages in a changing name order are picked by name, not position."""
    from ..sources.test_sources_mcap import write_joint_states

    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    joints, q = random_panda_parquet(examples_dir, "temporal_mcap_arm", reference, frames=12, seed=41)
    poses = random_poses(12, seed=42)
    rng = np.random.default_rng(43)
    messages = []
    for row in poses:
        order = rng.permutation(len(POSE_NAMES))
        messages.append(([POSE_NAMES[i] for i in order], [float(row[i]) for i in order]))
    write_joint_states(examples_dir / "data" / "temporal_base.mcap", messages)
    data = panda_config(examples_dir, "temporal_mcap", joints, [TEMPORAL_EDGE])
    data["sources"]["base_pose"] = {"mcap": "data/temporal_base.mcap", "topic": "/joint_states", "names": POSE_NAMES}
    result = run_cli("run", str(write_config(examples_dir, "temporal_mcap", data)))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "ros2_timestamp")
    times = sorted(frames.temporal["panda_link0"])
    assert len(times) == 12
    for index in (0, 5, 11):
        assert_poses_match(frames.world_pose("panda_link0", times[index], "world"), expected_pose(poses[index]), f"base at {index}")

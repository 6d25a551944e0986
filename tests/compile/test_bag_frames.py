"""A ROS 2 bag that carries its own robot (/robot_description) and frames (/tf_static): a real bag written with the
MCAP ROS 2 writer, run end to end, the recorded poses checked against pinocchio composed with the bag's transforms."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("mcap_ros2", reason="writing ROS 2 bags needs mcap-ros2-support (a test dependency)")

from ..bag_inputs import write_robot_bag
from ..edge_helpers import RIG_URDF, matrix, write_config
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames, rotation_angle

MOUNT = ("cam", "camera_optical", (0.01, -0.02, 0.05), (-0.5, 0.5, -0.5, 0.5))  # a camera's optical frame on its mount
LIDAR_MOUNT = ("lidar", "lidar_scan", (0.0, 0.0, 0.03), (0.0, 0.0, 0.3826834, 0.9238795))
DUPLICATE = ("adapter", "cam", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))  # what the URDF's adapter_to_cam joint places


def base_poses(rows: int) -> list[tuple[tuple[float, float, float], tuple[float, float, float, float]]]:
    """A base driving a curve in odom: translation and a yaw quaternion per row."""
    s = np.linspace(0.0, 2.0, rows)
    return [
        ((float(x), float(0.3 * x * x), 0.1), (0.0, 0.0, float(np.sin(y / 2)), float(np.cos(y / 2))))
        for x, y in zip(s, 0.8 * s, strict=True)
    ]


def _bag(directory: Path, q: np.ndarray) -> Path:
    path = directory / "data" / "robot.mcap"
    old = RIG_URDF.replace('name="rig"', 'name="old_rig"')  # republished: the last description is the robot
    moving = [[("odom", "base", t, quaternion), ("map", "odom", (1.0, 2.0, 0.0), (0, 0, 0, 1))] for t, quaternion in base_poses(len(q))]
    write_robot_bag(path, [old, RIG_URDF], [[MOUNT, DUPLICATE], [LIDAR_MOUNT]], ["shoulder"], q[:, None], moving)
    return path


def _config(edges: list[dict[str, Any]], urdf: Any = None) -> dict[str, Any]:
    return {
        "version": 1,
        "sources": {"js": {"mcap": "data/robot.mcap", "topic": "/joint_states"}},
        "robots": {
            "rig": {"urdf": urdf or {"mcap": "data/robot.mcap"}, "joints": {"source": "js", "unit": "rad", "map": {"shoulder": "shoulder"}}}
        },
        "frames": {"root": "base"},
        "edges": edges,
        "output": {"path": "out/{segment}.rrd", "application_id": "bag_frames", "segment": "bag"},
    }


MOUNT_EDGES = [
    {"parent": "cam", "child": "camera_optical", "tf_static": "data/robot.mcap"},
    {"parent": "lidar", "child": "lidar_scan", "tf_static": "data/robot.mcap", "topic": "/tf_static"},
]


@pytest.fixture
def bag_dir(tmp_path: Path) -> tuple[Path, np.ndarray]:
    q = np.sin(np.linspace(0.0, 3.0, 40)) * 1.5
    _bag(tmp_path, q)
    return tmp_path, q


def test_run_places_the_bag_robot_and_its_mounts_as_pinocchio_does(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    directory, q = bag_dir
    config = write_config(directory, "bag", _config(MOUNT_EDGES))
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    (directory / "rig.urdf").write_text(RIG_URDF, encoding="utf-8")
    reference = PinocchioRobot(directory / "rig.urdf")
    frames = read_frames(directory / "out" / "bag.rrd", "ros2_timestamp")
    times = sorted(frames.temporal["arm"])
    assert len(times) == len(q)
    mounts = {child: (parent, matrix(t, quaternion)) for parent, child, t, quaternion in (MOUNT, LIDAR_MOUNT)}
    for row in (0, 17, 39):
        links = reference.link_poses({"shoulder": float(q[row])})
        for child, (parent, local) in mounts.items():
            expected = links[parent] @ local
            got = frames.world_pose(child, times[row], "base")
            assert np.allclose(got[:3, 3], expected[:3, 3], atol=1e-5), (child, row)
            assert rotation_angle(got, expected) < 1e-5, (child, row)


def test_a_moving_base_from_tf_lines_up_with_the_joint_states(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    """/tf's odom -> base on the header stamps of the JointStates' timeline; map -> odom in the bag is not taken."""
    directory, q = bag_dir
    config = _config([*MOUNT_EDGES, {"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    result = run_cli("run", str(write_config(directory, "moving", config)))
    assert result.code == 0, result.err
    (directory / "rig.urdf").write_text(RIG_URDF, encoding="utf-8")
    reference = PinocchioRobot(directory / "rig.urdf")
    frames = read_frames(directory / "out" / "bag.rrd", "ros2_timestamp")
    times = sorted(frames.temporal["arm"])
    assert sorted(frames.temporal["base"]) == times  # one base pose per joint state, at the same stamps
    assert "odom" not in frames.temporal and "odom" not in frames.static
    poses = base_poses(len(q))
    for row in (0, 21, 39):
        links = reference.link_poses({"shoulder": float(q[row])})
        base = matrix(*poses[row])
        for child, parent, local in (("camera_optical", "cam", matrix(MOUNT[2], MOUNT[3])), ("arm", "arm", np.eye(4))):
            expected = base @ links[parent] @ local
            got = frames.world_pose(child, times[row], "odom")
            assert np.allclose(got[:3, 3], expected[:3, 3], atol=1e-5), (child, row)
            assert rotation_angle(got, expected) < 1e-5, (child, row)


def test_the_origin_names_the_bag(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    directory, _ = bag_dir
    result = run_cli("plan", "--format", "json", str(write_config(directory, "bag", _config(MOUNT_EDGES))))
    assert result.code == 0, result.err
    assert "mcap data/robot.mcap topic /robot_description" in result.out + result.err


@pytest.mark.parametrize(
    ("edges", "urdf", "expected"),
    [
        (
            [{"parent": "cam", "child": "camera_optcal", "tf_static": "data/robot.mcap"}],
            None,
            "'/tf_static' of robot.mcap has no transform for child frame 'camera_optcal' (did you mean 'camera_optical'?); "
            "its child frames: cam, camera_optical, lidar_scan",
        ),
        (
            [{"parent": "base", "child": "camera_optical", "tf_static": "data/robot.mcap"}],
            None,
            "'/tf_static' of robot.mcap places 'camera_optical' in 'cam', not in 'base'; write parent: cam",
        ),
        (
            [{"parent": "adapter", "child": "cam", "tf_static": "data/robot.mcap"}],
            None,
            "frame 'cam' has two parents: 'adapter' (URDF 'rig' joint 'adapter_to_cam' of robot 'rig') and 'adapter' (edges[0]",
        ),
        (
            [{"parent": "cam", "child": "camera_optical", "tf_static": "data/robot.mcap", "topic": "/joint_states"}],
            None,
            "topic '/joint_states' of robot.mcap carries sensor_msgs/msg/JointState (cdr), not ROS 2 tf2_msgs/msg/TFMessage (cdr)",
        ),
        ([{"parent": "cam", "child": "x", "tf_static": "data/none.mcap"}], None, "MCAP file not found"),
        (
            [],
            {"mcap": "data/robot.mcap", "topic": "/robot_descr"},
            "topic '/robot_descr' not in robot.mcap; its std_msgs/msg/String topics: /robot_description",
        ),
        ([], {"mcap": "s3://bucket/robot.mcap"}, "MCAP file s3://bucket/robot.mcap is a URL; it is read from a local path"),
        (
            [{"parent": "odom", "child": "base_lnk", "tf": "js"}],
            None,
            "'/tf' of robot.mcap has no transform for child frame 'base_lnk'; its child frames: base, odom",
        ),
        (
            [{"parent": "map", "child": "base", "tf": "js"}],
            None,
            "'/tf' of robot.mcap places 'base' in 'odom', not in 'map'; write parent: odom",
        ),
        ([{"parent": "odom", "child": "base", "tf": "nope"}], None, "no source named 'nope'; sources are: js"),
        (
            [{"parent": "odom", "child": "base", "tf": "js", "topic": "/tf_moving"}],
            None,
            "topic '/tf_moving' not in robot.mcap; its tf2_msgs/msg/TFMessage topics: /tf, /tf_static",
        ),
    ],
    ids=[
        "unknown_child",
        "wrong_parent",
        "duplicates_urdf_joint",
        "not_tf",
        "no_file",
        "urdf_topic_absent",
        "urdf_url",
        "tf_unknown_child",
        "tf_wrong_parent",
        "tf_unknown_source",
        "tf_topic_absent",
    ],
)
def test_validate_refuses(bag_dir: tuple[Path, np.ndarray], run_cli, edges: list[dict[str, Any]], urdf: Any, expected: str) -> None:
    directory, _ = bag_dir
    config = write_config(directory, "bad", _config(edges, urdf))
    result = run_cli("validate", str(config))
    assert result.code == 1, result.err
    assert expected in result.err, result.err
    assert "bad.yaml:" in result.err  # located


def test_a_huge_description_is_refused_from_the_summary(tmp_path: Path, run_cli) -> None:
    """17 MiB of description: refused before Rerun's reader decodes any of it (a 2 GB one the same way)."""
    huge = RIG_URDF.replace("</robot>", "<!--" + "x" * (17 * 2**20) + "--></robot>")
    write_robot_bag(tmp_path / "data" / "robot.mcap", [huge], [], ["shoulder"], np.zeros((3, 1)))
    result = run_cli("validate", str(write_config(tmp_path, "huge", _config([]))))
    assert result.code == 1
    assert "topic '/robot_description' of robot.mcap is held in" in result.err
    assert "over the cap of 16,777,216" in result.err


def test_frame_names_from_the_bag_are_shown_escaped(tmp_path: Path, run_cli) -> None:
    hostile = "cam\x1b[31m\nerror: forged" + "y" * 5000
    write_robot_bag(
        tmp_path / "data" / "robot.mcap", [RIG_URDF], [[("cam", hostile, (0, 0, 0), (0, 0, 0, 1))]], ["shoulder"], np.zeros((3, 1))
    )
    edges = [{"parent": "cam", "child": "camera_optical", "tf_static": "data/robot.mcap"}]
    result = run_cli("validate", str(write_config(tmp_path, "hostile", _config(edges))))
    assert result.code == 1
    assert "\x1b" not in result.err
    assert "\nerror: forged" not in result.err
    assert len(result.err) < 2000


def test_live_refuses_a_tf_edge(bag_dir: tuple[Path, np.ndarray]) -> None:
    from urdf_pipeline.compile import FROM_STREAM, check_config

    directory, _ = bag_dir
    config = _config([*MOUNT_EDGES, {"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    check = check_config(write_config(directory, "live", config), FROM_STREAM)
    assert [e.message for e in check.errors] == [
        "edge odom -> base reads /tf of source 'js''s bag, which run reads and a live view does not; drop the edge for live use"
    ]


def test_a_child_only_the_data_can_check_is_refused_after_the_pass(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    """A globbed bag's frames are checked in the data pass: a child never on /tf is zero rows, and nothing is written."""
    directory, _ = bag_dir
    config = _config([*MOUNT_EDGES, {"parent": "arm", "child": "wheel", "tf": "js"}])
    config["sources"]["js"]["mcap"] = "data/robot*.mcap"
    config["output"]["segment"] = "{stem}"
    result = run_cli("run", str(write_config(directory, "glob", config)))
    assert result.code == 1
    assert "temporal edge arm -> wheel (edges[2], source 'js', /tf of its bag): source 'js' yielded zero rows" in result.err
    assert not (directory / "out" / "robot.rrd").exists()


def test_tf_follows_the_sources_log_time_timeline(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    directory, q = bag_dir
    config = _config([*MOUNT_EDGES, {"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    config["sources"]["js"]["timeline"] = "log_time"
    result = run_cli("run", str(write_config(directory, "log_time", config)))
    assert result.code == 0, result.err
    frames = read_frames(directory / "out" / "bag.rrd", "message_log_time")
    assert sorted(frames.temporal["base"]) == sorted(frames.temporal["arm"])
    assert len(frames.temporal["base"]) == len(q)


def test_zero_header_stamps_on_tf_are_refused(tmp_path: Path, run_cli) -> None:
    moving = [[("odom", "base", (0.0, 0.0, 0.0), (0, 0, 0, 1))]] * 3
    path = tmp_path / "data" / "robot.mcap"
    write_robot_bag(path, [RIG_URDF], [[MOUNT]], ["shoulder"], np.zeros((3, 1)), moving, tf_stamps_ns=[0, 0, 0])
    config = _config([{"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    result = run_cli("run", str(write_config(tmp_path, "zero", config)))
    assert result.code == 1
    assert "transforms of base on /tf of source 'js''s bag have a zero header stamp (3 of 3 in one batch)" in result.err


def test_plan_says_where_a_tf_edge_comes_from(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    directory, _ = bag_dir
    config = _config([{"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    result = run_cli("plan", str(write_config(directory, "plan", config)))
    assert result.code == 0, result.err
    assert "temporal edge odom -> base on /calibration/temporal/base (edges[0], line" in result.out
    assert "its transforms on /tf of source 'js''s bag, on the source's timeline" in result.out
    markdown = run_cli("plan", str(directory / "plan.yaml"), "--format", "markdown")
    assert "per message: the bag's `/tf` of source `js`" in markdown.out, markdown.out
    assert "translation.x" not in markdown.out


def test_validate_no_data_leaves_tf_frames_to_the_data(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    """--no-data opens no source file: a /tf child the bag lacks is found by validate, not by validate --no-data."""
    directory, _ = bag_dir
    config = _config([{"parent": "arm", "child": "wheel", "tf": "js"}])
    config["sources"]["js"]["names"] = ["shoulder"]
    path = write_config(directory, "nodata", config)
    assert run_cli("validate", "--no-data", str(path)).code == 0
    refused = run_cli("validate", str(path))
    assert refused.code == 1
    assert "has no transform for child frame 'wheel'" in refused.err


def test_diff_says_a_tf_edge_was_added(bag_dir: tuple[Path, np.ndarray], run_cli) -> None:
    directory, _ = bag_dir
    old = write_config(directory, "old", _config(MOUNT_EDGES))
    config = _config([*MOUNT_EDGES, {"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    result = run_cli("diff", str(old), str(write_config(directory, "new", config)))
    assert "temporal edge odom -> base: added (source js, /tf of its bag)" in result.out, result.out + result.err


def test_a_frame_the_bag_reparents_is_refused(tmp_path: Path, run_cli) -> None:
    """odom -> base, then map -> base: refused by validate; in a globbed bag (frames checked in the data pass), by run."""
    moving = [[("odom", "base", (0.0, 0.0, 0.0), (0, 0, 0, 1))]] * 3 + [[("map", "base", (0.0, 0.0, 0.0), (0, 0, 0, 1))]]
    write_robot_bag(tmp_path / "data" / "robot.mcap", [RIG_URDF], [[MOUNT]], ["shoulder"], np.zeros((4, 1)), moving)
    config = _config([{"parent": "odom", "child": "base", "tf": "js"}])
    config["frames"]["root"] = "odom"
    refused = run_cli("validate", str(write_config(tmp_path, "reparent", config)))
    assert "'/tf' of robot.mcap places 'base' in 'map', not in 'odom'; a frame has one parent; fix the bag's publishers" in refused.err
    config["sources"]["js"]["mcap"] = "data/robot*.mcap"
    config["output"]["segment"] = "{stem}"
    result = run_cli("run", str(write_config(tmp_path, "reparent", config)))
    assert result.code == 1
    assert "/tf of source 'js''s bag places 'base' in 'map' in 1 transforms of one batch, not in 'odom'" in result.err
    assert not (tmp_path / "out" / "robot.rrd").exists()

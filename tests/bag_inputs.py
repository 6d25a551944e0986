"""ROS 2 bags that carry their own robot and frames, written with the MCAP ROS 2 writer (mcap-ros2-support): a
robot description on /robot_description, static mounts on /tf_static, a moving base on /tf, joint states."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mcap_ros2.writer import Writer

from urdf_pipeline.examples import JOINT_STATE_MSGDEF

T0_NS = 1_700_000_000_000_000_000
STEP_NS = 10_000_000

TF_MESSAGE_MSGDEF = """geometry_msgs/TransformStamped[] transforms
================================================================================
MSG: geometry_msgs/TransformStamped
std_msgs/Header header
string child_frame_id
Transform transform
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: geometry_msgs/Transform
Vector3 translation
Quaternion rotation
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
"""

# (parent, child, translation, quaternion_xyzw)
Transform = tuple[str, str, Sequence[float], Sequence[float]]


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 10**9, "nanosec": ns % 10**9}


def _tf_message(stamp_ns: int, transforms: Sequence[Transform]) -> dict[str, object]:
    return {
        "transforms": [
            {
                "header": {"stamp": _stamp(stamp_ns), "frame_id": parent},
                "child_frame_id": child,
                "transform": {
                    "translation": dict(zip("xyz", map(float, translation), strict=True)),
                    "rotation": dict(zip("xyzw", map(float, quaternion), strict=True)),
                },
            }
            for parent, child, translation, quaternion in transforms
        ]
    }


def write_robot_bag(
    path: Path,
    descriptions: Sequence[str],
    static: Sequence[Sequence[Transform]],
    joint_names: Sequence[str] = (),
    joint_values: np.ndarray | None = None,
    moving: Sequence[Sequence[Transform]] = (),
    tf_stamps_ns: Sequence[int] | None = None,
) -> list[int]:
    """`descriptions` in order on /robot_description (the last is the robot), each list of `static` one /tf_static
    message, `joint_values` [N, K] one JointState per row, `moving` one /tf message per row (stamped as the row,
    or `tf_stamps_ns`). Returns the stamps."""
    rows = len(joint_values) if joint_values is not None else len(moving)
    stamps = [T0_NS + i * STEP_NS for i in range(rows)]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as stream:
        writer = Writer(stream)
        text = writer.register_msgdef("std_msgs/msg/String", "string data\n")
        tf = writer.register_msgdef("tf2_msgs/msg/TFMessage", TF_MESSAGE_MSGDEF)
        joint_state = writer.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        for description in descriptions:
            writer.write_message("/robot_description", text, {"data": description}, log_time=T0_NS, publish_time=T0_NS)
        for transforms in static:
            writer.write_message("/tf_static", tf, _tf_message(T0_NS, transforms), log_time=T0_NS, publish_time=T0_NS)
        for row, stamp in enumerate(stamps):
            log_time = stamp + 2_000_000
            if joint_values is not None:
                message = {
                    "header": {"stamp": _stamp(stamp), "frame_id": ""},
                    "name": list(joint_names),
                    "position": [float(v) for v in joint_values[row]],
                    "velocity": [],
                    "effort": [],
                }
                writer.write_message("/joint_states", joint_state, message, log_time=log_time, publish_time=log_time)
            if row < len(moving):
                tf_stamp = tf_stamps_ns[row] if tf_stamps_ns is not None else stamp
                writer.write_message("/tf", tf, _tf_message(tf_stamp, moving[row]), log_time=log_time, publish_time=log_time)
        writer.finish()
    return stamps

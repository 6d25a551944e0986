"""Shared by the edge-kind tests (sidecar files, fixed chains, assume_identity, temporal edges)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from urdf_pipeline.examples import write_joint_parquet

from .execute.test_fk_against_pinocchio import PANDA_ARM, panda_contract_raw, random_within_limits
from .reference_fk import PinocchioRobot
from .rrd_frames import quat_xyzw_to_matrix

# A robot without meshes whose fixed joints carry arbitrary rotations, with a branch and a moving joint in the middle:
#   base -fixed-> mount -fixed-> bracket -shoulder (revolute)-> arm -fixed-> flange -fixed-> adapter -fixed-> cam
#   base -fixed-> lidar                                                        flange -fixed-> tool
RIG_URDF = """<?xml version="1.0"?>
<robot name="rig">
  <link name="base"/><link name="mount"/><link name="bracket"/><link name="arm"/>
  <link name="flange"/><link name="adapter"/><link name="cam"/><link name="tool"/><link name="lidar"/>
  <joint name="base_to_mount" type="fixed">
    <parent link="base"/><child link="mount"/><origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.5 1.1"/>
  </joint>
  <joint name="mount_to_bracket" type="fixed">
    <parent link="mount"/><child link="bracket"/><origin xyz="0.05 0.02 -0.04" rpy="-1.2 0.4 2.5"/>
  </joint>
  <joint name="shoulder" type="revolute">
    <parent link="bracket"/><child link="arm"/><origin xyz="0 0 0.2" rpy="0.1 0.2 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="arm_to_flange" type="fixed">
    <parent link="arm"/><child link="flange"/><origin xyz="0.4 0 0" rpy="0 1.5 0"/>
  </joint>
  <joint name="flange_to_adapter" type="fixed">
    <parent link="flange"/><child link="adapter"/><origin xyz="0.01 0.03 0.07" rpy="2.9 -0.7 -2.2"/>
  </joint>
  <joint name="adapter_to_cam" type="fixed">
    <parent link="adapter"/><child link="cam"/><origin xyz="-0.02 0.05 0.01" rpy="-0.4 1.3 0.6"/>
  </joint>
  <joint name="flange_to_tool" type="fixed">
    <parent link="flange"/><child link="tool"/><origin xyz="0 0 0.12"/>
  </joint>
  <joint name="base_to_lidar" type="fixed">
    <parent link="base"/><child link="lidar"/><origin xyz="0.2 0 0.5" rpy="0 0 3.0"/>
  </joint>
</robot>
"""


def write_rig(directory: Path) -> Path:
    path = directory / "robots" / "rig.urdf"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(RIG_URDF, encoding="utf-8")
    return path


def rig_config(segment: str, parquet: str, edges: list[dict[str, Any]], frame_prefix: str = "", root: str = "world") -> dict[str, Any]:
    return {
        "version": 1,
        "sources": {"rig_state": {"parquet": parquet, "column": "observation.state", "index": "frame_index", "names": ["q"]}},
        "robots": {
            "rig": {"urdf": "robots/rig.urdf", "frame_prefix": frame_prefix, "joints": {"source": "rig_state", "map": {"q": "shoulder"}}}
        },
        "frames": {"root": root},
        "edges": edges,
        "output": {"path": "out/{segment}.rrd", "application_id": "edge_kinds", "segment": segment},
    }


def panda_config(directory: Path, segment: str, parquet: str, edges: list[dict[str, Any]]) -> dict[str, Any]:
    """demo.yaml (degrees, j2 sign -1, j3 offset 0.1, finger in mm) with other joint values and edges."""
    data = yaml.safe_load((directory / "demo.yaml").read_text())
    data["sources"]["arm_state"]["parquet"] = parquet
    data["edges"] = edges
    data["output"]["segment"] = segment
    return data


def write_config(directory: Path, name: str, data: dict[str, Any]) -> Path:
    path = directory / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def random_panda_parquet(directory: Path, name: str, reference: PinocchioRobot, frames: int, seed: int) -> tuple[str, np.ndarray]:
    """Random joint values within limits (radians), written in the demo config's units; returns (relative path, q)."""
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=frames, seed=seed)
    relative = f"data/{name}.parquet"
    write_joint_parquet(directory / relative, panda_contract_raw(q))
    return relative, q


def matrix(translation, quaternion_xyzw) -> np.ndarray:
    result = np.eye(4)
    result[:3, :3] = quat_xyzw_to_matrix(list(quaternion_xyzw))
    result[:3, 3] = translation
    return result

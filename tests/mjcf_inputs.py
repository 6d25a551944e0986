"""Small robot descriptions the MJCF and URDF tests and the invalid-config cases use: a two-link arm in MJCF that
exercises what MuJoCo's compiler knows (degrees, a defaults class, euler and axisangle orientations, an include,
meshdir with an STL, a hinge off its body's origin, a slide, a ref), hostile or unrepresentable variants of it (a
DOCTYPE, size bombs), and a URDF declaring entities."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import yaml

from urdf_pipeline.examples import write_joint_parquet

ARM = """<mujoco model="mjcf_arm">
  <compiler angle="degree" meshdir="mjcf_meshes" eulerseq="zyx"/>
  <default>
    <default class="arm"><joint axis="0 1 0" range="-120 120"/><geom type="capsule" size="0.03"/></default>
  </default>
  <include file="mjcf_arm_assets.xml"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="target" mocap="true" pos="0.3 0 0.2" quat="0 1 0 0"><geom type="sphere" size="0.02"/></body>
    <body name="base" pos="0 0 0.1" euler="30 10 0">
      <joint name="shoulder" type="hinge" axis="0 0 1" range="-170 170" pos="0.02 0 0"/>
      <geom type="mesh" mesh="tetra" pos="0.01 0 0"/>
      <body name="upper" pos="0 0 0.2" axisangle="1 0 0 20" childclass="arm">
        <joint name="elbow" pos="0 0.01 -0.05" ref="15"/>
        <geom fromto="0 0 0 0 0 0.3"/>
        <body name="lower" pos="0 0 0.3" xyaxes="0 1 0 -1 0 0">
          <joint name="wrist" type="slide" axis="1 0 0" range="-0.05 0.05"/>
          <joint name="twist" axis="0 0 1" pos="0.03 0 0" range="-90 90"/>
          <geom type="box" size="0.02 0.03 0.04"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
ASSETS = '<mujoco><asset><mesh name="tetra" file="tetra.stl" scale="0.1 0.1 0.1"/></asset></mujoco>\n'
ARM_JOINTS = ("shoulder", "elbow", "wrist", "twist")
# Four nested replicates of 100: 10^8 bodies from a few hundred bytes.
REPLICATE_BOMB = "<mujoco><worldbody>{}</worldbody></mujoco>".format(
    '<replicate count="100" offset="0.1 0 0">' * 4 + '<body><geom size="0.01"/></body>' + "</replicate>" * 4
)
# MuJoCo's XML reader (TinyXML2) ends a DOCTYPE at its first '>': the include inside this comment is MuJoCo's only.
DOCTYPE_HIDING = '<!DOCTYPE mujoco [<!-- > <mujoco><include file="{}"/></mujoco> -->]>\n'
# A URDF whose link name is an entity: expat would expand it, ROS's parser (TinyXML2) would not.
URDF_ENTITIES = """<?xml version="1.0"?>
<!DOCTYPE robot [<!ENTITY base "base_link">]>
<robot name="r"><link name="&base;"/><link name="l1"/>
  <joint name="j1" type="revolute"><parent link="&base;"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""


def tetrahedron_stl() -> bytes:
    """A binary STL of a tetrahedron (84 + 50 n bytes, as Rerun and MuJoCo read it)."""
    corners = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    data = bytearray(b"\0" * 80 + struct.pack("<I", len(faces)))
    for face in faces:
        data += struct.pack("<3f", 0.0, 0.0, 0.0)
        for corner in face:
            data += struct.pack("<3f", *corners[corner])
        data += b"\0\0"
    return bytes(data)


def write_mjcf_inputs(robots: Path) -> None:
    """robots/mjcf_arm.xml (with its include and mesh) and the variants the invalid cases name."""
    (robots / "mjcf_meshes").mkdir(parents=True, exist_ok=True)
    (robots / "mjcf_meshes" / "tetra.stl").write_bytes(tetrahedron_stl())
    (robots / "mjcf_arm_assets.xml").write_text(ASSETS, encoding="utf-8")
    (robots / "mjcf_arm.xml").write_text(ARM, encoding="utf-8")
    variants = {
        "include_outside": ARM.replace('file="mjcf_arm_assets.xml"', 'file="/etc/hostname"'),
        "meshdir_outside": ARM.replace('meshdir="mjcf_meshes"', 'meshdir="/etc"'),
        "free_nested": ARM.replace(
            '<joint name="wrist" type="slide" axis="1 0 0" range="-0.05 0.05"/>', '<freejoint name="loose"/>'
        ).replace('<joint name="twist" axis="0 0 1" pos="0.03 0 0" range="-90 90"/>', ""),
        "unknown_element": ARM.replace("<worldbody>", "<worldbody><gizmo/>"),
        "doctype": DOCTYPE_HIDING.format("/etc/hostname") + ARM,
        "replicate_bomb": REPLICATE_BOMB,
    }
    for name, text in variants.items():
        (robots / f"mjcf_arm_{name}.xml").write_text(text, encoding="utf-8")
    (robots / "urdf_entities.urdf").write_text(URDF_ENTITIES, encoding="utf-8")


def robot_config(directory: Path, urdf: object, joint: str = "j1") -> Path:
    """`robot.yaml` in `directory`: one robot whose `urdf` entry is `urdf`, its joint `joint` driven by a three-row
    parquet source; what `validate` reads of it is the robot description alone."""
    directory.mkdir(parents=True, exist_ok=True)
    write_joint_parquet(directory / "d.parquet", np.zeros((3, 1)))
    config = {
        "version": 1,
        "sources": {"s": {"parquet": "d.parquet", "column": "observation.state", "index": "frame_index", "names": ["j"]}},
        "robots": {"arm": {"urdf": urdf, "joints": {"source": "s", "map": {"j": joint}}}},
        "output": {"path": "out/x.rrd", "application_id": "x", "segment": "x"},
    }
    path = directory / "robot.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path

"""Forward kinematics as arrays: composed down the tree, against pinocchio (fixed, revolute, prismatic joints with
rotated origins and a non-unit axis) and, for a floating joint, against what Rerun logs for it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from urdf_pipeline.execute.joint_fk import ClosedFormJointTransforms
from urdf_pipeline.execute.kinematics import RobotKinematics

from ..reference_fk import PinocchioRobot
from .test_fk_against_pinocchio import assert_poses_match
from .test_joint_fk import _tree

ARM = """<robot name="a">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="turn" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0.1 0 0.3" rpy="0.2 -0.4 1.1"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0 0.2 0" rpy="1.5708 0 0"/>
    <axis xyz="0 0 2"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="tip" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.05 0 0.1" rpy="0 0.3 0"/></joint>
</robot>"""


def test_composed_poses_equal_pinocchio(tmp_path: Path) -> None:
    tree = _tree(ARM, tmp_path)
    values = np.random.default_rng(3).uniform(-1, 1, (20, 2))
    kinematics = RobotKinematics.of("a", "base", ClosedFormJointTransforms(tree, ["turn", "slide"]).link_poses(values), {})
    links = kinematics.links
    reference = PinocchioRobot(tmp_path / "robot.urdf")
    for row in (0, 7, 19):
        for link, expected in reference.link_poses({"turn": values[row, 0], "slide": values[row, 1]}).items():
            assert_poses_match(kinematics.matrices()[links.index(link), row], expected, f"{link} at {row}")


def test_a_floating_joint_is_placed_as_rerun_logs_it(tmp_path: Path) -> None:
    """Rerun's model logs a floating joint's origin as its static edge: the arrays place it there too."""
    text = ARM.replace('<link name="base"/>', '<link name="world"/><link name="base"/>').replace(
        "</robot>",
        '<joint name="free" type="floating"><parent link="world"/><child link="base"/><origin xyz="1 2 3" rpy="0 0 0.5"/></joint></robot>',
    )
    tree = _tree(text, tmp_path)
    kinematics = RobotKinematics.of("a", "world", ClosedFormJointTransforms(tree, ["turn", "slide"]).link_poses(np.zeros((4, 2))), {})
    links, translations, quaternions = kinematics.links, kinematics.translations, kinematics.quaternions
    logged = {}
    for chunk in tree.stream(include_joint_transforms=True):
        batch = chunk.to_record_batch().to_pydict()
        for child, translation, quaternion in zip(
            batch.get("Transform3D:child_frame", []),
            batch.get("Transform3D:translation", []),
            batch.get("Transform3D:quaternion", []),
            strict=False,
        ):
            logged[child[0]] = (translation[0], quaternion[0])
    index = links.index("base")
    assert links[0] == "world"
    np.testing.assert_allclose(translations[index], np.tile(logged["base"][0], (4, 1)), atol=1e-6)
    np.testing.assert_allclose(quaternions[index], np.tile(logged["base"][1], (4, 1)), atol=1e-6)

"""The closed-form joint transforms against Rerun's own FK, over every URDF the sweep knows (the sweep itself checks
the written poses against pinocchio), and the fallback to Rerun's FK when the two would disagree."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest
from rerun.urdf import UrdfTree

from urdf_pipeline.execute.joint_fk import ClosedFormJointTransforms
from urdf_pipeline.urdf import parse_urdf, text_for_rerun
from urdf_pipeline.urdf.model import MOVING_TYPES

from ..urdf.test_urdf_sweep import reference_text, sweep_cases

PANDA = """<robot name="p">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.333" rpy="0.1 -1.2 2.9"/>
    <axis xyz="0 0 1"/><limit lower="-2.9" upper="2.9" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0.2 -0.1 0" rpy="-1.5708 0 0.3"/>
    <axis xyz="0.6 0 0.8"/><limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>
  <joint name="fixed_tip" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0 0 0.1"/></joint>
</robot>"""


def _tree(text: str, directory: Path, prefix: str | None = None) -> UrdfTree:
    repaired, _ = text_for_rerun(text, "robot.urdf")
    path = directory / "robot.urdf"
    path.write_text(repaired, encoding="utf-8")
    return UrdfTree.from_file_path(path, frame_prefix=prefix)


def _assert_same(ours: object, theirs: object) -> None:
    a, b = ours.values, theirs.values  # type: ignore[attr-defined]
    assert a.field("parent_frame").equals(b.field("parent_frame")) and a.field("child_frame").equals(b.field("child_frame"))
    t = [np.asarray(v.field("translation").flatten()).reshape(-1, 3) for v in (a, b)]
    q = [np.asarray(v.field("quaternion").flatten()).reshape(-1, 4) for v in (a, b)]
    assert np.abs(t[0] - t[1]).max() <= 1e-5
    assert np.minimum(np.abs(q[0] - q[1]).max(axis=1), np.abs(q[0] + q[1]).max(axis=1)).max() <= 1e-5


def test_closed_form_equals_rerun_with_a_prefix_and_a_non_unit_prismatic_axis(tmp_path: Path) -> None:
    tree = _tree(PANDA, tmp_path, prefix="left/")
    fk = ClosedFormJointTransforms(tree, ["slide", "j1"])  # not in file order
    assert fk.usable
    values = np.random.default_rng(1).uniform(-4.0, 4.0, (300, 2))  # far past the limits: FK does not clamp
    ours = fk(values)
    assert ours.type == fk._rerun(values).type
    _assert_same(ours, fk._rerun(values))
    assert ours.values.field("parent_frame").to_pylist()[:2] == ["left/l1", "left/base"]


def test_a_joint_it_does_not_know_leaves_the_robot_to_rerun(tmp_path: Path) -> None:
    tree = _tree(PANDA, tmp_path)
    fk = ClosedFormJointTransforms(tree, ["j1", "fixed_tip"])
    assert not fk.usable
    values = np.array([[0.5, 0.0], [1.0, 0.0]])
    assert fk(values).equals(fk._rerun(values))


def test_the_check_at_construction_catches_a_wrong_formula(tmp_path: Path) -> None:
    fk = ClosedFormJointTransforms(_tree(PANDA, tmp_path), ["j1", "slide"])
    assert fk._agrees_with_rerun()
    fk.axis_q32 = -fk.axis_q32  # turning the wrong way
    assert not fk._agrees_with_rerun()


@pytest.mark.slow
def test_every_sweep_urdf_rerun_loads_gets_the_closed_form(tmp_path: Path) -> None:
    """No robot falls back: the closed form covers every moving joint of both description packages."""
    checked, fallbacks = 0, []
    for case in sweep_cases():
        try:
            with contextlib.redirect_stderr(io.StringIO()):
                text = reference_text(case)
                parse_urdf(text, case.source)
                tree = _tree(text, tmp_path)
        except Exception:  # refused by the pipeline or by Rerun's loader: the sweep covers those
            continue
        names = [joint.name for joint in tree.joints() if joint.joint_type in MOVING_TYPES]
        if not names:
            continue
        fk = ClosedFormJointTransforms(tree, names)
        if not fk.usable:
            fallbacks.append(case.source)
            continue
        values = np.random.default_rng(checked).uniform(-3.5, 3.5, (40, len(names)))
        _assert_same(fk(values), fk._rerun(values))
        checked += 1
    assert not fallbacks
    assert checked >= 60

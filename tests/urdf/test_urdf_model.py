"""The URDF as ROS reads it: structure errors name their joint or link, axes are normalised, and what Rerun's loader
refuses but ROS tolerates is repaired (with a warning) so the poses still equal pinocchio's."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from urdf_pipeline.examples import example_robot_data_share, write_joint_parquet
from urdf_pipeline.urdf.model import UrdfParseError, parse_urdf_text
from urdf_pipeline.urdf.repair import rerun_loader_error, text_for_rerun

from .test_urdf_sweep import SweepCase, run_case

ARM = """<?xml version="1.0"?>
<robot name="arm">
  <material name="blue"><color rgba="0 0 1 1"/></material>
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><origin xyz="0 0 0.1"/><geometry><box size="0.1 0.1 0.2"/></geometry><material name="blue"/></visual>
  </link>
  <link name="upper"><visual><geometry><cylinder radius="0.05" length="0.3"/></geometry></visual></link>
  <link name="slider"/>
  <link name="wrist"/>
  <link name="finger"/>
  <link name="tip"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.2" rpy="0.1 0.2 0.3"/>
    <axis xyz="0 0 2.5"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="upper"/><child link="slider"/>
    <origin xyz="0.1 0 0.3" rpy="0 0.5 0"/>
    <axis xyz="0 3 4"/>
    <limit lower="-0.5" upper="0.5" effort="1" velocity="1"/>
  </joint>
  <joint name="twist" type="continuous">
    <parent link="slider"/><child link="wrist"/>
    <origin xyz="0 0.2 0" rpy="-0.4 0 0.2"/>
    <axis xyz="1 1 0"/>
  </joint>
  <joint name="grip" type="revolute">
    <parent link="wrist"/><child link="finger"/>
    <origin xyz="0 0 0.05"/>
    <axis xyz="0.6 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="twist" multiplier="0.5" offset="0.1"/>
  </joint>
  <joint name="tool" type="fixed">
    <parent link="finger"/><child link="tip"/>
    <origin xyz="0 0 0.1" rpy="0 0 1"/>
    <axis xyz="0 0 0"/>
  </joint>
</robot>
"""


def edit(text: str, *replacements: tuple[str, str]) -> str:
    for old, new in replacements:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text


def problems(text: str) -> tuple[str, ...]:
    with pytest.raises(UrdfParseError) as caught:
        parse_urdf_text(text, "arm.urdf")
    return caught.value.messages


# --- the model ---


def test_axes_are_normalised_in_the_model() -> None:
    model = parse_urdf_text(ARM, "arm.urdf")
    assert model.joint("shoulder").axis == (0.0, 0.0, 1.0)  # type: ignore[union-attr]
    assert model.joint("slide").axis == pytest.approx((0.0, 0.6, 0.8))  # type: ignore[union-attr]
    assert model.joint("twist").axis == pytest.approx((math.sqrt(0.5), math.sqrt(0.5), 0.0))  # type: ignore[union-attr]
    assert model.joint("tool").axis == (0.0, 0.0, 0.0)  # type: ignore[union-attr]  # a fixed joint does not use it


@pytest.mark.parametrize(
    ("replacement", "expected"),
    [
        (('<axis xyz="0 3 4"/>', '<axis xyz="0 0 0"/>'), "joint 'slide' (prismatic) has axis 0 0 0"),
        (('<axis xyz="0 3 4"/>', "<axis/>"), "joint 'slide' (prismatic) has an <axis> without xyz (ROS reads it as 0 0 0)"),
        (
            ('<parent link="upper"/>', '<parent link="uper"/>'),
            "joint 'slide' names parent link 'uper', which the URDF does not define (did you mean 'upper'?)",
        ),
        (('<child link="tip"/>', '<child link="tool_tip"/>'), "joint 'tool' names child link 'tool_tip', which the URDF does not define"),
        (('<child link="tip"/>', '<child link="wrist"/>'), "link 'wrist' is the child of two joints, 'twist' and 'tool'"),
        (('<link name="tip"/>', '<link name="tip"/><link name="wrist"/>'), "two <link> elements are named 'wrist'"),
        (('<joint name="grip"', '<joint name="twist"'), "two <joint> elements are named 'twist'"),
        (('<mimic joint="twist"', '<mimic joint="twisst"'), "joint 'grip' mimics 'twisst', which the URDF lacks (did you mean 'twist'?)"),
        (('<mimic joint="twist"', '<mimic joint="tool"'), "joint 'grip' mimics 'tool', a fixed joint that never moves"),
        (('<mimic joint="twist"', '<mimic joint="grip"'), "joints mimic each other in a cycle: grip -> grip"),
        (('type="continuous">', 'type="Continuous">'), "joint 'twist' has type 'Continuous'; a URDF joint is one of"),
        (('xyz="0 0.2 0"', 'xyz="0 0.2"'), "joint 'twist': <origin xyz> '0 0.2' is not 3 numbers"),
        (('lower="-1" upper="1"', 'lower="-inf" upper="1"'), "joint 'grip': <limit lower> '-inf' is not a number"),
        (('multiplier="0.5"', 'multiplier="nan"'), "joint 'grip': <mimic multiplier> 'nan' is not a number"),
        (('<link name="tip"/>', '<link name="tip"/><link name="loose"/>'), "expected one root link, found 2: base, loose"),
    ],
)
def test_structure_errors_name_the_culprit(replacement: tuple[str, str], expected: str) -> None:
    found = problems(edit(ARM, replacement))
    assert any(expected in message for message in found), found
    assert all(re.match(r"arm\.urdf(:\d+)?: ", message) for message in found), found


def test_a_problem_points_at_its_line_in_the_urdf() -> None:
    """ROS users read the URDF, not our model: the message gives the line of the joint or link at fault."""
    text = edit(ARM, ('<parent link="upper"/>', '<parent link="uper"/>'), ('<link name="tip"/>', '<link name="tip"/><link name="wrist"/>'))
    line_of = {
        name: text.splitlines().index(line) + 1 for line in text.splitlines() for name in ("slide", "tip") if f'name="{name}"' in line
    }
    assert problems(text) == (
        f"arm.urdf:{line_of['tip']}: two <link> elements are named 'wrist'; URDF link names must be unique",
        f"arm.urdf:{line_of['slide']}: joint 'slide' names parent link 'uper', which the URDF does not define (did you mean 'upper'?); "
        'fix the joint\'s <parent link="..."/> or add <link name="uper"/>',
    )
    with pytest.raises(UrdfParseError) as caught:
        parse_urdf_text(text, "arm.urdf", source_lines=False)  # expanded from xacro: its lines are not the file's
    assert caught.value.messages[0].startswith("arm.urdf: two <link>")


def test_a_mimic_cycle_of_two_is_reported_once() -> None:
    text = edit(ARM, ('type="continuous">', 'type="continuous"><mimic joint="grip"/>'))
    assert problems(text) == ("arm.urdf:25: joints mimic each other in a cycle: twist -> grip -> twist; one of them must be driven",)


def test_every_problem_is_reported_at_once() -> None:
    text = edit(ARM, ('<parent link="upper"/>', '<parent link="uper"/>'), ('<axis xyz="1 1 0"/>', '<axis xyz="0 0 0"/>'))
    assert len(problems(text)) == 2


def test_links_cut_off_in_a_cycle_are_refused() -> None:
    cycle = '<link name="a"/><link name="b"/><joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>'
    cycle += '<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>'
    text = edit(ARM, ("</robot>", cycle + "</robot>"))
    assert problems(text) == ("arm.urdf: links a, b form a cycle of joints, cut off from root link 'base'",)


def test_deep_nesting_is_refused_not_a_crash() -> None:
    text = edit(ARM, ('<link name="tip"/>', '<link name="tip">' + "<gazebo>" * 5000 + "</gazebo>" * 5000 + "</link>"))
    assert problems(text) == ("arm.urdf:12: elements nested more than 100 levels deep",)


def test_no_link_and_no_xml() -> None:
    assert problems('<robot name="r"/>') == ("arm.urdf: the URDF defines no <link>",)
    assert problems("hello")[0].startswith("arm.urdf is not valid XML")


def test_read_as_ros_reads_it() -> None:
    """The first of a repeated element counts; a default XML namespace changes nothing; a <mimic> on a fixed joint is moot."""
    text = edit(
        ARM,
        ('<origin xyz="0 0 0.05"/>', '<origin xyz="0 0 0.05"/><origin xyz="9 9 9"/>'),
        ('<robot name="arm">', '<robot name="arm" xmlns="http://www.ros.org">'),
        ('rpy="0 0 1"/>', 'rpy="0 0 1"/><mimic joint="twist"/>'),
    )
    model = parse_urdf_text(text, "arm.urdf")
    assert model.joint("grip").xyz == (0.0, 0.0, 0.05)  # type: ignore[union-attr]
    assert model.joint("tool").mimic is None  # type: ignore[union-attr]
    assert model.root_link == "base"


# --- the text Rerun receives ---


def test_a_urdf_that_needs_nothing_is_handed_over_unchanged() -> None:
    text = edit(
        ARM, ('<axis xyz="0 0 2.5"/>', '<axis xyz="0 0 1"/>'), ('"0 3 4"', '"0 0.6 0.8"'), ('"1 1 0"', '"1 0 0"'), ('"0.6 0 0"', '"1 0 0"')
    )
    assert text_for_rerun(text, "arm.urdf") == (text, ())


def test_rerun_receives_unit_axes() -> None:
    text, notes = text_for_rerun(ARM, "arm.urdf")
    assert notes == ()  # normalising is URDF semantics, not a repair
    model = parse_urdf_text(text, "arm.urdf")
    assert model.joint("shoulder").axis == (0.0, 0.0, 1.0)  # type: ignore[union-attr]
    assert 'xyz="0.0 0.6 0.8"' in text
    assert rerun_loader_error(text) is None


REPAIRS = [
    (
        "empty texture",
        ('<color rgba="0 0 1 1"/>', '<texture/><color rgba="0 0 1 1"/>'),
        "<texture> without filename removed (in material 'blue')",
    ),
    (
        "material without name",
        ('<material name="blue"/>', '<material><color rgba="1 0 0 1"/></material>'),
        "<material> without name removed",
    ),
    ("color without rgba", ('<color rgba="0 0 1 1"/>', "<color/>"), "<color> whose rgba is not 4 numbers removed"),
    ("rgb color", ('<color rgba="0 0 1 1"/>', '<color rgba="0 0 1"/>'), "<color> whose rgba is not 4 numbers removed"),
    ("no mass", ('<mass value="1"/>', ""), "malformed <inertial> removed (ROS drops it too) (in link 'base')"),
    ("partial inertia", (' iyz="0" izz="1"', ""), "malformed <inertial> removed"),
    (
        "box of two",
        ('size="0.1 0.1 0.2"', 'size="0.1 0.1"'),
        "<visual> with a malformed <geometry> or <origin> removed (ROS drops it too) (in link 'base')",
    ),
    (
        "cylinder without length",
        (' length="0.3"', ""),
        "<visual> with a malformed <geometry> or <origin> removed (ROS drops it too) (in link 'upper')",
    ),
    ("mesh scale of one", ('<box size="0.1 0.1 0.2"/>', '<mesh filename="m.stl" scale="0.001"/>'), "<visual> with a malformed <geometry>"),
    (
        "empty geometry",
        ('<geometry><cylinder radius="0.05" length="0.3"/></geometry>', "<geometry> </geometry>"),
        "<visual> with a malformed",
    ),
    (
        "two shapes",
        ('<box size="0.1 0.1 0.2"/>', '<box size="0.1 0.1 0.2"/><sphere radius="1"/>'),
        "a second shape in a <geometry> removed",
    ),
    (
        "two origins",
        ('<origin xyz="0 0 0.05"/>', '<origin xyz="0 0 0.05"/><origin xyz="9 9 9"/>'),
        "a second <origin> in a <joint> removed (ROS reads the first) (in joint 'grip')",
    ),
    ("fixed axis without xyz", ('<axis xyz="0 0 0"/>', "<axis/>"), "<axis> without xyz removed from a joint that does not use it"),
]


@pytest.mark.parametrize(("replacement", "note"), [pytest.param(r, n, id=i) for i, r, n in REPAIRS])
def test_what_rerun_refuses_but_ros_tolerates_is_repaired(replacement: tuple[str, str], note: str) -> None:
    broken = edit(ARM, replacement)
    parse_urdf_text(broken, "arm.urdf")  # ROS reads it
    text, notes = text_for_rerun(broken, "arm.urdf")
    assert any(note in n for n in notes), notes
    assert rerun_loader_error(text) is None
    repaired = parse_urdf_text(text, "arm.urdf")
    assert [j.xyz for j in repaired.joints] == [j.xyz for j in parse_urdf_text(ARM, "arm.urdf").joints]


def test_repeated_repairs_are_counted() -> None:
    _, notes = text_for_rerun(
        edit(
            ARM,
            ("<visual><geometry><cylinder", '<visual><material name="m"><texture/></material><geometry><cylinder'),
            ('<color rgba="0 0 1 1"/>', '<texture/><color rgba="0 0 1 1"/>'),
        ),
        "arm.urdf",
    )
    assert notes == ("<texture> without filename removed (2x, first in material 'blue')",)


def test_what_ros_refuses_too_is_a_loader_error() -> None:
    broken = edit(ARM, (' effort="1" velocity="1"/>\n  </joint>\n  <joint name="twist"', '/>\n  </joint>\n  <joint name="twist"'))
    text, _ = text_for_rerun(broken, "arm.urdf")
    assert rerun_loader_error(text) == "custom: missing field `velocity`"


# --- end to end: validate, run, compare with pinocchio ---


def test_repaired_urdf_with_non_unit_axes_matches_pinocchio(tmp_path: Path) -> None:
    """Non-unit axes (revolute, prismatic, continuous, mimic) and every kind of repair at once, through the real CLI."""
    broken = edit(
        ARM,
        ('<color rgba="0 0 1 1"/>', '<texture/><color rgba="0 0 1 1"/>'),
        ('<mass value="1"/>', ""),
        ('<origin xyz="0 0 0.05"/>', '<origin xyz="0 0 0.05"/><origin xyz="9 9 9"/>'),
        ("<visual><geometry><cylinder", '<visual><geometry><box size="1 1"/></geometry></visual><visual><geometry><cylinder'),
    )
    (tmp_path / "arm.urdf").write_text(broken, encoding="utf-8")
    outcome = run_case(SweepCase("arm", "arm.urdf", str(tmp_path / "arm.urdf")), tmp_path)
    assert outcome.kind == "match", outcome.detail


def _validate(tmp_path: Path, urdf_text: str, run_cli) -> tuple[Path, Any]:
    (tmp_path / "arm.urdf").write_text(urdf_text, encoding="utf-8")
    (tmp_path / "data").mkdir(exist_ok=True)
    config = {
        "version": 1,
        "sources": {"q": {"parquet": "data/q.parquet", "column": "observation.state", "index": "frame_index", "names": ["s", "p", "t"]}},
        "robots": {
            "arm": {
                "urdf": "arm.urdf",
                "joints": {"source": "q", "map": {"s": "shoulder", "p": {"joint": "slide", "unit": "m"}, "t": "twist"}},
            }
        },
        "frames": {"root": "world"},
        "edges": [{"parent": "world", "child": "base", "translation": [0, 0, 0], "quaternion_xyzw": [0, 0, 0, 1]}],
        "output": {"path": "out/{segment}.rrd", "application_id": "arm", "segment": "arm"},
    }
    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    write_joint_parquet(tmp_path / "data" / "q.parquet", np.zeros((2, 3)))
    return path, run_cli("validate", str(path))


def test_a_joint_naming_a_missing_link_is_reported_at_the_urdf(tmp_path: Path, run_cli) -> None:
    config, result = _validate(tmp_path, edit(ARM, ('<parent link="upper"/>', '<parent link="uper"/>')), run_cli)
    assert result.code == 1, result.err
    lines = [line for line in result.err.splitlines() if line.startswith("error")]
    assert lines == [
        f"error: {config}:13:5: robots.arm.urdf: {tmp_path / 'arm.urdf'}:19: joint 'slide' names parent link 'uper', which the URDF does not "
        'define (did you mean \'upper\'?); fix the joint\'s <parent link="..."/> or add <link name="uper"/>'
    ], result.err
    assert "calibration edge" not in result.err


def test_every_urdf_problem_is_one_error_line(tmp_path: Path, run_cli) -> None:
    text = edit(ARM, ('<child link="tip"/>', '<child link="wrist"/>'), ('<mimic joint="twist"', '<mimic joint="grip"'))
    _, result = _validate(tmp_path, text, run_cli)
    assert result.code == 1
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    assert len(errors) == 2 and "Traceback" not in result.err
    assert "link 'wrist' is the child of two joints, 'twist' and 'tool'" in errors[0]
    assert "joints mimic each other in a cycle: grip -> grip" in errors[1]


def test_a_repair_is_a_warning_and_validate_passes(tmp_path: Path, run_cli) -> None:
    _, result = _validate(tmp_path, edit(ARM, ('<color rgba="0 0 1 1"/>', '<texture/><color rgba="0 0 1 1"/>')), run_cli)
    assert result.code == 0, result.err
    assert "warning: " in result.err and "robots.arm.urdf: Rerun's URDF loader refuses parts of arm.urdf that ROS tolerates" in result.err
    assert "<texture> without filename removed (in material 'blue')" in result.err


def test_what_rerun_cannot_load_is_refused_by_validate(tmp_path: Path, run_cli) -> None:
    """A file ROS refuses too (a <limit> without effort): a user error from validate, never exit 70 from run."""
    text = edit(ARM, (' effort="1" velocity="1"/>\n  </joint>\n  <joint name="twist"', '/>\n  </joint>\n  <joint name="twist"'))
    _, result = _validate(tmp_path, text, run_cli)
    assert result.code == 1
    assert "robots.arm.urdf: Rerun's URDF loader cannot read arm.urdf: custom: missing field `velocity`" in result.err


def test_icub_validates_with_a_note_on_its_empty_textures(tmp_path: Path, run_cli) -> None:
    icub = example_robot_data_share() / "robots" / "icub_description" / "robots" / "icub.urdf"
    text, notes = text_for_rerun(icub.read_text(encoding="utf-8"), "icub.urdf")
    assert rerun_loader_error(icub.read_text(encoding="utf-8")) == "custom: missing field `filename`"
    assert rerun_loader_error(text) is None
    assert notes == ("<texture> without filename removed (28x, first in link 'chest')",)


def test_the_fast_loader_check_is_rerun_s_own_loader(tmp_path: Path) -> None:
    """rerun_loader_error uses the compiled loader behind rerun.urdf.UrdfTree (importing rerun takes ~1 s): same verdicts."""
    from rerun.urdf import UrdfTree

    broken = tmp_path / "broken.urdf"
    broken.write_text(edit(ARM, ('<color rgba="0 0 1 1"/>', '<texture/><color rgba="0 0 1 1"/>')), encoding="utf-8")
    with pytest.raises(RuntimeError, match="missing field `filename`"):
        UrdfTree.from_file_path(broken)
    assert rerun_loader_error(broken.read_text(encoding="utf-8")) == "custom: missing field `filename`"
    assert rerun_loader_error(ARM) is None

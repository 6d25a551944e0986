"""URDF files as they really are: xacro content in a `.urdf` is refused in every form (never a robot reduced to its
root link), a <link> or <joint> outside <robot>'s top level is refused, and blank lines before `<?xml ...?>` are
read as ROS, pinocchio and pybullet read them, through to a recording whose poses equal pinocchio's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf.model import UrdfParseError, parse_urdf_text
from urdf_pipeline.urdf.repair import rerun_loader_error, text_for_rerun
from urdf_pipeline.urdf.xml_text import XacroContent

from ..execute.test_fk_against_pinocchio import (
    PANDA_ARM,
    check_robot,
    panda_contract_raw,
    panda_joint_values,
    random_within_limits,
    variant,
)
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames
from .test_urdf_sources import offline_git, so101_description_cache, so101_robot, write_config  # noqa: F401 (a fixture)

XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'
JOINT = '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'


def robot(body: str, attributes: str = XACRO_NS) -> str:
    """A two-link URDF whose <robot> also holds `body`, one element a line (body's lines start at line 3)."""
    return f'<?xml version="1.0"?>\n<robot name="r" {attributes}>\n{body}\n<link name="base"/>\n<link name="l1"/>\n{JOINT}\n</robot>\n'


def refusal(text: str) -> UrdfParseError:
    with pytest.raises(UrdfParseError) as caught:
        parse_urdf_text(text, "arm.urdf")
    return caught.value


# --- xacro content ----------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("body", "attributes", "found"),
    [
        ('<xacro:include filename="parts.xacro"/>', XACRO_NS, '<xacro:include filename="parts.xacro">'),
        ('<xacro:arm prefix="left_"/>', XACRO_NS, '<xacro:arm prefix="left_">'),  # a macro call
        ('<xacro:property name="l" value="0.3"/>', XACRO_NS, '<xacro:property name="l">'),  # its first attribute
        ('<x:macro name="m"><link name="m"/></x:macro>', 'xmlns:x="http://ros.org/wiki/xacro"', '<x:macro name="m">'),
        ('<xacro:include filename="p.xacro"/>', "", '<xacro:include filename="p.xacro">'),  # undeclared prefix: still xacro
        ('<link name="${prefix}tool"/>', XACRO_NS, '<link name="${prefix}tool">'),
        (
            '<link name="v"><visual><geometry><mesh filename="$(find arm)/m.stl"/></geometry></visual></link>',
            "",
            '<mesh filename="$(find arm)/m.stl">',
        ),
        ('<link name="$(arg side)_hand"/>', "", '<link name="$(arg side)_hand">'),
    ],
    ids=["include", "macro-call", "property", "other-prefix", "undeclared", "expression", "find", "arg"],
)
def test_xacro_content_is_refused_naming_the_first_xacro_element_and_its_line(body: str, attributes: str, found: str) -> None:
    error = refusal(robot(body, attributes))
    assert isinstance(error, XacroContent)
    assert (error.line, error.found) == (3, found)
    assert error.messages == (error.advice("expand it as xacro: urdf: {xacro: arm.urdf}"),)
    assert error.messages[0].startswith(f"arm.urdf:3: {found} is xacro: this file is a xacro file, not a URDF")


def test_the_first_xacro_element_is_named_when_there_are_several() -> None:
    error = refusal(robot('<link name="a${x}"/>\n<xacro:include filename="p.xacro"/>'))
    assert isinstance(error, XacroContent) and error.line == 3 and error.found == '<link name="a${x}">'


@pytest.mark.parametrize(
    "body",
    [
        "",  # xmlns:xacro left on <robot> by xacro itself (example-robot-data's panda.urdf has it)
        '<material name="cost$1"><texture filename="m/$name.png"/></material>',  # a $ alone is no xacro
        '<gazebo reference="l1"><material>Gazebo/Grey</material></gazebo>',
    ],
    ids=["namespace-only", "dollar", "gazebo"],
)
def test_a_urdf_that_only_looks_like_xacro_is_read(body: str) -> None:
    model = parse_urdf_text(robot(body), "arm.urdf")
    assert model.joint("j1") is not None


# --- links and joints outside <robot>'s top level ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("body", "shown", "parent"),
    [
        ('<group>\n<link name="hand"/>\n</group>', '<link name="hand">', "<group> (line 3)"),
        ('<link name="hand">\n<joint name="inner" type="fixed"/>\n</link>', '<joint name="inner">', "<link> (line 3)"),
        ('<sdf version="1.6">\n<link name="hand"/>\n</sdf>', '<link name="hand">', "<sdf> (line 3)"),
    ],
    ids=["link-in-group", "joint-in-link", "link-in-unknown"],
)
def test_a_nested_link_or_joint_is_refused_naming_it_and_its_line(body: str, shown: str, parent: str) -> None:
    error = refusal(robot(body, ""))
    tag = shown.split()[0].removeprefix("<")
    assert not isinstance(error, XacroContent)
    assert error.messages == (
        f"arm.urdf:4: {shown} is inside {parent}, not directly inside <robot>: URDF readers (ROS, pinocchio, Rerun) ignore "
        f"a <{tag}> anywhere else, so the robot would silently lose it; move it to the top level of <robot>",
    )


@pytest.mark.parametrize(
    "body",
    [
        '<transmission name="t"><type>SimpleTransmission</type><joint name="j1"><hardwareInterface>E</hardwareInterface></joint></transmission>',
        '<gazebo><plugin name="p" filename="libp.so"><joint name="j1"/><link name="l1"/></plugin></gazebo>',
        '<ros2_control name="c" type="system"><joint name="j1"><command_interface name="position"/></joint></ros2_control>',
    ],
    ids=["transmission", "gazebo", "ros2_control"],
)
def test_extensions_that_hold_their_own_joint_elements_are_read(body: str) -> None:
    model = parse_urdf_text(robot(body, ""), "arm.urdf")
    assert [j.name for j in model.joints] == ["j1"] and model.links == ("base", "l1")


# --- blank lines before the XML declaration ---------------------------------------------------------------------------


@pytest.mark.parametrize("leading", ["\n\n  ", "\t \r\n", "\ufeff\n", " "], ids=["blank-lines", "crlf", "bom", "space"])
def test_blank_lines_before_the_declaration_are_read_and_lines_stay_the_file_s(leading: str) -> None:
    text = leading + robot("")
    model = parse_urdf_text(text, "arm.urdf")
    assert model.root_link == "base" and model.joint("j1") is not None
    broken = leading + robot("<link/>")  # a link without a name, on the file's line 3 + the leading line breaks
    assert refusal(broken).messages == (f'arm.urdf:{3 + leading.count(chr(10))}: a <link> has no name="..."',)
    assert text_for_rerun(text, "arm.urdf") == (text, ())  # Rerun's loader reads it as it is
    assert rerun_loader_error(text) is None


def test_a_declaration_that_is_not_first_for_another_reason_is_still_an_xml_error() -> None:
    text = '<!-- a comment -->\n<?xml version="1.0"?>\n<robot name="r"><link name="a"/></robot>'
    assert "is not valid XML" in refusal(text).messages[0]


# --- every URDF form ---------------------------------------------------------------------------------------------------

CONFIG_ROBOT = {"urdf": "arm.urdf", "joints": {"source": "state", "map": {"j": "j1"}}}


def test_validate_and_run_refuse_xacro_content_at_the_urdf_key(tmp_path: Path, run_cli) -> None:
    """The issue's case: a `.urdf` that is xacro used to validate and to write a recording of its root link alone."""
    (tmp_path / "arm.urdf").write_text(robot('<xacro:include filename="parts.xacro"/>\n<xacro:arm prefix="left_"/>'))
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((3, 1)))
    config = write_config(tmp_path, "arm", CONFIG_ROBOT, ["j"], "d.parquet")
    for command in ("validate", "run"):
        result = run_cli(command, str(config))
        assert result.code == 1, result.err
        errors = [line for line in result.err.splitlines() if line.startswith("error")]
        assert len(errors) == 1, result.err
        assert errors[0].startswith(f"error: {config}:11:5: robots.arm.urdf: {tmp_path / 'arm.urdf'}:3: ")
        assert '<xacro:include filename="parts.xacro"> is xacro' in errors[0]
        assert "urdf: {xacro: arm.urdf}" in errors[0]
    assert not (tmp_path / "out").exists()


def test_validate_refuses_a_nested_link_at_the_urdf_key(tmp_path: Path, run_cli) -> None:
    (tmp_path / "arm.urdf").write_text(robot('<group name="left">\n<link name="hand"/>\n</group>', ""))
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((3, 1)))
    config = write_config(tmp_path, "arm", CONFIG_ROBOT, ["j"], "d.parquet")
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert f'error: {config}:11:5: robots.arm.urdf: {tmp_path / "arm.urdf"}:4: <link name="hand"> is inside <group>' in result.err


def test_init_refuses_xacro_content_given_as_urdf(tmp_path: Path, run_cli) -> None:
    (tmp_path / "arm.urdf").write_text(robot('<xacro:include filename="parts.xacro"/>'))
    result = run_cli("init", "--urdf", str(tmp_path / "arm.urdf"), "-o", str(tmp_path / "arm.yaml"))
    assert result.code == 1 and "Traceback" not in result.err
    assert f'{tmp_path / "arm.urdf"}:3: <xacro:include filename="parts.xacro"> is xacro' in result.err
    assert f"use --xacro {tmp_path / 'arm.urdf'}" in result.err
    assert not (tmp_path / "arm.yaml").exists()


def test_robot_descriptions_giving_xacro_content_is_refused(tmp_path: Path, run_cli, monkeypatch, offline_git, erd_share: Path) -> None:  # noqa: F811
    commit = so101_description_cache(tmp_path, monkeypatch, erd_share)
    urdf = tmp_path / "cache" / f"SO-ARM100-{commit}" / "SO-ARM100" / "Simulation" / "SO101" / "so101_new_calib.urdf"
    text = urdf.read_text()
    start = text.index(">", text.index("<robot")) + 1
    urdf.write_text(text[:start] + '<xacro:include filename="extras.xacro"/>' + text[start:])
    joints = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((5, 6)))
    result = run_cli("validate", str(write_config(tmp_path, "so101_rd", so101_robot(), joints, "d.parquet")))
    assert result.code == 1 and "Traceback" not in result.err
    assert "robots.arm.urdf: " in result.err and '<xacro:include filename="extras.xacro"> is xacro' in result.err
    assert "robot_descriptions 'so_arm101_description' gives a file that is a xacro file" in result.err
    assert f"urdf: {{xacro: {urdf.resolve()}}}" in result.err


def test_a_urdf_with_blank_lines_before_its_declaration_runs_and_matches_pinocchio(examples_dir: Path, run_cli) -> None:
    robots = examples_dir / "robots"
    leading = robots / "panda_leading_space.urdf"
    leading.write_text("\n\n  " + (robots / "panda.urdf").read_text(encoding="utf-8"), encoding="utf-8")
    reference = PinocchioRobot(leading)  # pinocchio reads the file as it is, too
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=16, seed=21)
    write_joint_parquet(examples_dir / "data" / "random_panda_leading.parquet", panda_contract_raw(q))

    def edit(data: dict) -> None:
        data["sources"]["arm_state"].update(parquet="data/random_panda_leading.parquet")
        data["robots"]["arm"]["urdf"] = "robots/panda_leading_space.urdf"

    config = variant(examples_dir, "demo.yaml", "fk_panda_leading_space", edit)
    assert yaml.safe_load(config.read_text())["robots"]["arm"]["urdf"] == "robots/panda_leading_space.urdf"
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "frame_index")
    world_from_base = np.eye(4)
    world_from_base[:3, 3] = [0.0, 0.0, 0.5]  # demo.yaml's calibration edge
    values = [panda_joint_values(row) for row in q]
    assert check_robot(frames, list(range(16)), reference, values, "", world_from_base, "world", [0, 15]) == 2 * 13

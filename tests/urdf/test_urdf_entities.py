"""A URDF means to this tool what it means to ROS's parser (urdfdom on TinyXML2, which reads no DTD and expands no
entity): a DOCTYPE declaring entities or naming an external DTD is refused, not expanded, in every form the text comes
in (a file, a robot_descriptions package's file, a bag's /robot_description, xacro's input files); a bare
`<!DOCTYPE robot>`, which both read alike, is read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf.model import UrdfParseError, parse_urdf_text

from ..bag_inputs import write_robot_bag
from ..mjcf_inputs import URDF_ENTITIES, robot_config
from .test_mjcf_files import refused
from .test_urdf_sources import offline_git, so101_description_cache, so101_robot, write_config  # noqa: F401 (a fixture)

XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'
JOINT = (
    '<link name="base"/><link name="l1"/><joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
    '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
)
BILLION_LAUGHS = (
    '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
    + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(9))
    + ']>\n<robot name="&j;">'
    + JOINT
    + "</robot>\n"
)


@pytest.mark.parametrize(
    ("doctype", "expected"),
    [
        ('<!DOCTYPE robot [<!ENTITY base "base">]>', "arm.urdf:2: <!DOCTYPE robot [...]> declares entities (an internal subset)"),
        ("<!DOCTYPE robot [<!-- > <robot name='hidden'/> -->]>", "arm.urdf:2: <!DOCTYPE robot [...]> declares entities"),
        ('<!DOCTYPE robot SYSTEM "urdf.dtd">', "arm.urdf:2: <!DOCTYPE robot ... 'urdf.dtd'> names an external DTD"),
        ('<!DOCTYPE robot PUBLIC "-//ROS//URDF" "urdf.dtd">', "names an external DTD"),
    ],
)
def test_a_doctype_ros_would_read_otherwise_is_refused(doctype: str, expected: str) -> None:
    with pytest.raises(UrdfParseError, match=r"ROS's URDF parser \(urdfdom, TinyXML2\) reads no DTD") as caught:
        parse_urdf_text(f'<?xml version="1.0"?>\n{doctype}\n<robot name="r">{JOINT}</robot>\n', "arm.urdf")
    assert expected in str(caught.value)


def test_a_bare_doctype_is_read() -> None:
    model = parse_urdf_text(f'<?xml version="1.0"?>\n<!DOCTYPE robot>\n<robot name="r">{JOINT}</robot>\n', "arm.urdf")
    assert model.root_link == "base"


def test_an_entity_bomb_is_refused_before_it_expands() -> None:
    with pytest.raises(UrdfParseError, match=r"arm.urdf:2: <!DOCTYPE robot \[...\]> declares entities"):
        parse_urdf_text(BILLION_LAUGHS, "arm.urdf")


def test_a_urdf_file_declaring_entities_is_refused_by_validate(tmp_path: Path, run_cli) -> None:
    (tmp_path / "arm.urdf").write_text(URDF_ENTITIES, encoding="utf-8")
    config = robot_config(tmp_path, "arm.urdf")
    refused(run_cli("validate", str(config)), config, f"{tmp_path / 'arm.urdf'}:2: <!DOCTYPE robot [...]> declares entities")

    (tmp_path / "arm.urdf").write_text(URDF_ENTITIES.replace(' [<!ENTITY base "base_link">]', "").replace("&base;", "base_link"))
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err


def test_a_bags_robot_description_declaring_entities_is_refused(tmp_path: Path, run_cli) -> None:
    write_robot_bag(tmp_path / "robot.mcap", [URDF_ENTITIES], [])
    config = robot_config(tmp_path, {"mcap": "robot.mcap"})
    refused(run_cli("validate", str(config)), config, "(line 2 of the expanded text): <!DOCTYPE robot [...]> declares entities")


def test_a_robot_descriptions_file_declaring_entities_is_refused(
    tmp_path: Path,
    run_cli,
    monkeypatch,
    offline_git,  # noqa: F811
    erd_share: Path,
) -> None:
    commit = so101_description_cache(tmp_path, monkeypatch, erd_share)
    urdf = tmp_path / "cache" / f"SO-ARM100-{commit}" / "SO-ARM100" / "Simulation" / "SO101" / "so101_new_calib.urdf"
    text = urdf.read_text()
    start = text.index("<robot")
    urdf.write_text(text[:start] + '<!DOCTYPE robot [<!ENTITY pan "shoulder_pan">]>\n' + text[start:])
    joints = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
    write_joint_parquet(tmp_path / "d.parquet", np.zeros((5, 6)))
    config = write_config(tmp_path, "so101_rd", so101_robot(), joints, "d.parquet")
    line = text[:start].count("\n") + 1
    refused(run_cli("validate", str(config)), config, f"so101_new_calib.urdf:{line}: <!DOCTYPE robot [...]> declares entities")


def _xacro(folder: Path, name: str, doctype: str, body: str = "") -> None:
    text = f'<?xml version="1.0"?>\n{doctype}\n<robot name="r" {XACRO_NS}>{body}</robot>\n'
    (folder / name).write_text(text, encoding="utf-8")


@pytest.mark.parametrize(
    ("main", "part", "expected"),
    [
        ('<!DOCTYPE robot [<!ENTITY n "base">]>', "", "xacro file arm.urdf.xacro:2: <!DOCTYPE robot [...]> declares entities"),
        (
            "<!DOCTYPE robot>",
            '<!DOCTYPE robot SYSTEM "x.dtd">',
            "xacro file part.xacro:2: <!DOCTYPE robot ... 'x.dtd'> names an external DTD",
        ),
    ],
)
def test_a_xacro_file_declaring_entities_is_refused(tmp_path: Path, run_cli, main: str, part: str, expected: str) -> None:
    """minidom, xacro's parser, expands internal entities and copies the subset into its output: refused before."""
    _xacro(tmp_path, "arm.urdf.xacro", main, '<xacro:include filename="part.xacro"/>' + JOINT)
    _xacro(tmp_path, "part.xacro", part)
    config = robot_config(tmp_path, {"xacro": "arm.urdf.xacro"})
    refused(run_cli("validate", str(config)), config, expected)


def test_a_xacro_file_with_a_bare_doctype_expands(tmp_path: Path, run_cli) -> None:
    _xacro(tmp_path, "arm.urdf.xacro", "<!DOCTYPE robot>", '<xacro:include filename="part.xacro"/>' + JOINT)
    _xacro(tmp_path, "part.xacro", "<!DOCTYPE robot>")
    result = run_cli("validate", str(robot_config(tmp_path, {"xacro": "arm.urdf.xacro"})))
    assert result.code == 0, result.err

"""`urdf-pipeline init`: the scaffolded config parses with the project's own compile_config, failing without data only on
the stub source file; with --source, names are read from metadata and pre-matched to the URDF's joints for review."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.compile.compiler import compile_config
from urdf_pipeline.errors import UserError, UserErrors
from urdf_pipeline.examples import write_joint_parquet, write_lerobot_dataset
from urdf_pipeline.scaffold.name_match import match_names
from urdf_pipeline.scaffold.source_probe import parse_source_spec
from urdf_pipeline.urdf.model import read_urdf

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

REPO = Path(__file__).resolve().parents[2]
ROBOTS = {
    "panda": "panda_description/urdf/panda.urdf",
    "so101": "so_arm_description/urdf/so101.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "g1": "g1_description/urdf/g1_29dof_rev_1_0.urdf",
    "pr2": "pr2_description/urdf/pr2.urdf",  # mimic, continuous and prismatic joints, 20 to drive
}


def errors_of(exc: UserError) -> list[UserError]:
    return exc.errors if isinstance(exc, UserErrors) else [exc]


def drivable(urdf: Path) -> list[str]:
    _, model = read_urdf(urdf)
    return [j.name for j in model.joints if j.moving and j.mimic is None]


@pytest.fixture
def init(run_cli, tmp_path: Path):
    def run(urdf: Path, *extra: str, name: str = "robot.yaml") -> tuple[Path, dict, str]:
        config = tmp_path / name
        result = run_cli("init", "--urdf", str(urdf), "-o", str(config), *extra)
        assert result.code == 0, result.err
        assert result.out == ""
        return config, yaml.safe_load(config.read_text()), config.read_text()

    return run


def only_robot(data: dict) -> dict:
    (robot,) = data["robots"].values()
    return robot


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_stub_fails_only_on_the_missing_file_and_compiles_with_data(robot: str, erd_share: Path, init) -> None:
    urdf = erd_share / "robots" / ROBOTS[robot]
    config, data, text = init(urdf)
    assert text.startswith("# yaml-language-server: $schema=")
    joints = drivable(urdf)
    (source,) = data["sources"].values()
    assert source["names"] == joints
    mapping = only_robot(data)["joints"]["map"]
    assert list(mapping) == joints  # the map keys equal the joint names
    assert [v if isinstance(v, str) else v["joint"] for v in mapping.values()] == joints

    with pytest.raises(UserError) as caught:
        compile_config(config)
    (error,) = errors_of(caught.value)
    assert "file not found" in error.message and error.where.path.endswith(".parquet")
    assert "TODO" in text.splitlines()[error.where.line - 1]  # the line it fails on is marked

    write_joint_parquet(config.parent / source["parquet"], np.zeros((4, len(joints))))
    plan = compile_config(config)
    (compiled,) = plan.robots
    assert sorted(c.joint for c in compiled.channels) == sorted(joints)
    _, model = read_urdf(urdf)
    assert sorted(m.joint for m in compiled.mimics) == sorted(j.name for j in model.joints if j.mimic is not None)
    assert plan.root_frame == "world"


def test_panda_comments_limits_mimic_and_prismatic_unit(erd_share: Path, init) -> None:
    _, data, text = init(erd_share / "robots" / ROBOTS["panda"])
    assert re.search(r"^\s+panda_joint1: panda_joint1\s+# revolute, -2\.8973 \.\. 2\.8973 rad$", text, re.M)
    assert "panda_finger_joint2" not in only_robot(data)["joints"]["map"]
    assert "# mimic (computed by the pipeline, not mapped): panda_finger_joint2 = panda_finger_joint1 * 1.0 + 0.0" in text
    assert only_robot(data)["joints"]["map"]["panda_finger_joint1"] == {"joint": "panda_finger_joint1", "unit": "m"}
    assert only_robot(data)["joints"]["unit"] == "rad" and re.search(r"unit: rad\s+# review: the unit", text)
    assert data["edges"] == [
        {"parent": "world", "child": "panda_link0", "translation": [0.0, 0.0, 0.0], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]}
    ]
    assert re.search(r"translation: .*# TODO: measure", text)
    assert data["output"] == {"path": "out/{segment}.rrd", "application_id": "panda", "segment": "episode_000"}


def test_package_paths_are_found_or_stubbed(erd_share: Path, examples_dir: Path, tmp_path: Path, init) -> None:
    _, data, text = init(examples_dir / "robots" / "panda.urdf", name="beside.yaml")  # robots/share/example-robot-data
    assert Path(only_robot(data)["package_paths"]["example-robot-data"]).is_absolute() is False
    assert (tmp_path / only_robot(data)["package_paths"]["example-robot-data"]).resolve() == erd_share.resolve()

    lonely = tmp_path / "lonely" / "panda.urdf"
    lonely.parent.mkdir()
    shutil.copy(erd_share / "robots" / ROBOTS["panda"], lonely)
    config, data, text = init(lonely, name="lonely.yaml")
    assert only_robot(data)["package_paths"] == {"example-robot-data": "TODO/example-robot-data"}
    with pytest.raises(UserError) as caught:
        compile_config(config)
    lines = text.splitlines()
    for error in errors_of(caught.value):  # each problem is on a line marked TODO
        assert "TODO" in lines[error.where.line - 1], error.message


def test_lerobot_so101_names_equal_the_urdf(examples_dir: Path, erd_share: Path, init) -> None:
    urdf = erd_share / "robots" / ROBOTS["so101"]
    config, data, text = init(urdf, "--source", f"lerobot:{examples_dir / 'data' / 'so101_lerobot'}")
    source = data["sources"]["so101_new_calib_state"]
    assert (config.parent / source["lerobot"]).resolve() == (examples_dir / "data" / "so101_lerobot").resolve()
    assert source["feature"] == "observation.state" and "episode" not in source
    mapping = only_robot(data)["joints"]["map"]
    assert mapping == {name: name for name in drivable(urdf)}
    assert text.count("# review: matched by name (score 1.00)") == 6
    assert data["output"]["segment"] == "episode_{episode:06d}"
    plan = compile_config(config)
    assert len(plan.segments) == 4


def test_g1_matches_the_hand_written_config(examples_dir: Path, init) -> None:
    urdf = examples_dir / "robots/share/example-robot-data/robots/g1_description/urdf/g1_29dof_rev_1_0.urdf"
    config, data, text = init(urdf, "--source", f"lerobot:{examples_dir / 'data' / 'g1_lerobot'}#observation.state")
    joints = only_robot(data)["joints"]
    expected = yaml.safe_load((examples_dir / "g1_held_joints.yaml").read_text())["robots"]["g1"]["joints"]
    assert joints["map"] == expected["map"]  # kLeftShoulderPitch -> left_shoulder_pitch_joint, ...
    assert joints["ignore"] == expected["ignore"]  # the hands
    assert joints["hold"] == expected["hold"]  # legs and waist at 0.0
    assert "kLeftShoulderPitch: left_shoulder_pitch_joint" in text and "# review: matched by name (score 1.00)" in text
    assert re.search(r"- kLeftHandPinky\s+# TODO: no URDF joint resembles it", text)
    assert re.search(r"waist_yaw_joint: 0\.0\s+# TODO: not in the data, held at 0\.0", text)
    assert only_robot(data)["package_paths"]["example-robot-data"].endswith("robots/share/example-robot-data")  # the symlink kept
    assert len(compile_config(config).segments) == 2


def test_similar_names_are_matched_for_review(erd_share: Path, tmp_path: Path, init) -> None:
    urdf = erd_share / "robots" / ROBOTS["so101"]
    names = ["ShoulderPan", "shoulder_lift.pos", "elbow", "WristFlex", "wrist_roll_deg", "Gripper", "temperature"]
    write_lerobot_dataset(tmp_path / "ds", np.zeros((5, len(names))), names)
    config, data, text = init(urdf, "--source", "lerobot:" + str(tmp_path / "ds"))
    joints = only_robot(data)["joints"]
    assert joints["map"] == {
        "ShoulderPan": "shoulder_pan",
        "shoulder_lift.pos": "shoulder_lift",
        "WristFlex": "wrist_flex",
        "wrist_roll_deg": "wrist_roll",
        "Gripper": "gripper",
    }
    assert re.search(r"shoulder_lift\.pos: shoulder_lift\s+# review: matched by name \(score 0\.83\)", text)
    assert re.search(r"wrist_roll_deg: wrist_roll\s+# review: matched by name \(score 0\.82\)", text)
    assert joints["ignore"] == ["elbow", "temperature"]  # 'elbow' alone is not similar enough to 'elbow_flex'
    assert joints["hold"] == {"elbow_flex": 0.0}
    compile_config(config)


def test_hold_is_mid_range_when_zero_is_outside_the_limits(erd_share: Path, tmp_path: Path, init) -> None:
    urdf = erd_share / "robots" / ROBOTS["panda"]
    names = [n for n in drivable(urdf) if n != "panda_joint4"]
    write_lerobot_dataset(tmp_path / "ds", np.zeros((5, len(names))), names)
    config, data, text = init(urdf, "--source", "lerobot:" + str(tmp_path / "ds"))
    assert only_robot(data)["joints"]["hold"] == {"panda_joint4": -1.5708}  # limits -3.0718 .. -0.0698
    compile_config(config)


def test_mcap_topic_found_and_root_link_world_needs_no_edge(examples_dir: Path, init) -> None:
    urdf = examples_dir / "robots/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
    config, data, text = init(urdf, "--source", str(examples_dir / "data" / "ur5_joint_states.mcap"))  # kind from the suffix
    assert data["sources"]["ur5_state"]["topic"] == "/joint_states"
    assert list(only_robot(data)["joints"]["map"]) == drivable(urdf)  # URDF order: message order is arbitrary
    assert "edges" not in data and "no calibration edge needed" in text
    assert compile_config(config).root_frame == "world"


def test_hdf5_glob_is_matched_by_position(examples_dir: Path, erd_share: Path, init) -> None:
    urdf = erd_share / "robots" / "z1_description/urdf/z1.urdf"
    config, data, text = init(urdf, "--source", f"hdf5:{examples_dir / 'data' / 'aloha'}/episode_*.hdf5#/observations/qpos")
    (source,) = data["sources"].values()
    joints = drivable(urdf)
    assert source["names"] == joints + [f"value_{i}" for i in range(len(joints), 14)]
    assert only_robot(data)["joints"]["ignore"] == [f"value_{i}" for i in range(len(joints), 14)]
    assert "# review: matched by position" in text and data["output"]["segment"] == "{stem}"
    assert len(compile_config(config).segments) == 3


def test_parquet_source_reads_the_schema(examples_dir: Path, init) -> None:
    config, data, text = init(
        examples_dir / "robots" / "panda.urdf", "--source", f"parquet:{examples_dir / 'data' / 'episode_000.parquet'}"
    )
    (source,) = data["sources"].values()
    assert source["column"] == "observation.state" and source["index"] == "frame_index"
    assert "parquet carries no names" in text
    compile_config(config)


def test_output_rules(erd_share: Path, tmp_path: Path, run_cli) -> None:
    urdf = str(erd_share / "robots" / ROBOTS["so101"])
    config = tmp_path / "so101.yaml"
    assert run_cli("init", "--urdf", urdf, "-o", str(config)).code == 0
    first = config.read_text()
    refused = run_cli("init", "--urdf", urdf, "-o", str(config))
    assert refused.code == 1 and "exists; --force overwrites it" in refused.err
    assert run_cli("init", "--urdf", urdf, "-o", str(config), "--force").code == 0
    assert config.read_text() == first  # deterministic
    schema_id = json.loads((REPO / "urdf_pipeline" / "data" / "urdf-pipeline.schema.json").read_text())["$id"]
    assert first.splitlines()[0] == f"# yaml-language-server: $schema={schema_id}"  # no schemas/ above: the URL, never a path
    assert schema_id.startswith("https://raw.githubusercontent.com/urdf-pipeline/urdf-pipeline/v")

    inside = tmp_path / "repo" / "configs"  # a repository holding the schema: a relative path to it
    assert run_cli("schema", "-o", str(tmp_path / "repo" / "schemas" / "urdf-pipeline.schema.json")).code == 0  # vendored
    assert run_cli("init", "--urdf", urdf, "-o", str(inside / "so101.yaml")).code == 0
    assert (inside / "so101.yaml").read_text().startswith("# yaml-language-server: $schema=../schemas/urdf-pipeline.schema.json\n")

    printed = run_cli("init", "--urdf", urdf)  # stdout: paths relative to the current directory
    assert printed.code == 0 and printed.out.startswith("# yaml-language-server:") and "file not found" in printed.err


def test_refusals(erd_share: Path, tmp_path: Path, run_cli) -> None:
    xacro = tmp_path / "arm.urdf.xacro"
    xacro.write_text("<robot/>")
    refused = run_cli("init", "--urdf", str(xacro)).err
    assert "xacro file" in refused and f"use --xacro {xacro}" in refused
    scene = tmp_path / "table.urdf"
    scene.write_text('<robot name="table"><link name="top"/></robot>')
    assert "no joint to drive" in run_cli("init", "--urdf", str(scene)).err
    urdf = str(erd_share / "robots" / ROBOTS["so101"])
    missing = run_cli("init", "--urdf", urdf, "--source", "lerobot:" + str(tmp_path / "nope"))
    assert missing.code == 1 and missing.err.startswith("error: --source lerobot:")
    assert "say which kind" in run_cli("init", "--urdf", urdf, "--source", str(tmp_path / "x.txt")).err


def test_source_spec_syntax(tmp_path: Path) -> None:
    assert parse_source_spec("lerobot:data/ds#action") == ("lerobot", "data/ds", "action")
    assert parse_source_spec("hdf5:a.hdf5#/observations/qpos") == ("hdf5", "a.hdf5", "/observations/qpos")
    assert parse_source_spec("bag.mcap") == ("mcap", "bag.mcap", None)
    assert parse_source_spec("x.parquet#observation.state") == ("parquet", "x.parquet", "observation.state")
    assert parse_source_spec("EP.H5#/qpos") == ("hdf5", "EP.H5", "/qpos")  # the suffixes come from the kinds
    (tmp_path / "ds" / "meta").mkdir(parents=True)
    (tmp_path / "ds" / "meta" / "info.json").write_text("{}")
    assert parse_source_spec(str(tmp_path / "ds")) == ("lerobot", str(tmp_path / "ds"), None)
    with pytest.raises(UserError) as caught:
        parse_source_spec(str(tmp_path / "x.txt"))
    assert caught.value.message.endswith(
        "lerobot:DIR[#FEATURE], parquet:FILE[#COLUMN], mcap:FILE[#TOPIC], hdf5:FILE#/DATASET, rrd:FILE#ENTITY or csv:FILE"
    )
    for remote in ("parquet:s3://robot-data/ep.parquet", "hf://datasets/lerobot/pusht@v2.1"):
        with pytest.raises(UserError, match="init reads a local file or dataset"):
            parse_source_spec(remote)


def test_name_matching_rules() -> None:
    def pairs(names: list[str], joints: list[str]) -> dict[str, str]:
        return {m.source_name: m.joint for m in match_names(names, joints)}

    assert pairs(["kLeftElbow", "kRightElbow"], ["right_elbow_joint", "left_elbow_joint"]) == {
        "kLeftElbow": "left_elbow_joint",
        "kRightElbow": "right_elbow_joint",
    }
    assert pairs(["l_wrist", "r_wrist"], ["left_wrist_joint", "right_wrist_joint"]) == {
        "l_wrist": "left_wrist_joint",
        "r_wrist": "right_wrist_joint",
    }
    assert pairs(["wrist_3"], ["wrist_1_joint", "wrist_2_joint"]) == {}  # numbers must agree
    assert pairs(["left_knee"], ["right_knee_joint"]) == {}  # sides must agree
    assert pairs(["j1", "j2", "finger"], ["panda_joint1", "panda_joint2", "panda_finger_joint1"]) == {
        "j1": "panda_joint1",
        "j2": "panda_joint2",
        "finger": "panda_finger_joint1",
    }
    assert pairs(["shoulder_pitch"], ["shoulder_roll_joint"]) == {}
    exact = match_names(["elbow_joint", "elbow"], ["elbow_joint"])  # an identical name wins a tie
    assert [(m.source_name, m.score) for m in exact] == [("elbow_joint", 1.0)]


@pytest.mark.parametrize("command", [["init", "--urdf", "URDF"], ["schema"]])
def test_an_output_under_a_file_is_a_user_error_naming_the_file(command: list[str], examples_dir: Path, run_cli, tmp_path: Path) -> None:
    """`-o` below a file (a folder cannot be made there): exit 1 naming the file in the way, nothing written."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    argv = [str(examples_dir / "robots" / "panda.urdf") if part == "URDF" else part for part in command]
    result = run_cli(*argv, "-o", str(blocker / "out.yaml"))
    assert result.code == 1, result.err
    assert result.err.strip().endswith(f"{blocker} is a file, not a folder") and "Traceback" not in result.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]

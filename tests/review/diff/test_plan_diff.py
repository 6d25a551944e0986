"""`urdf-pipeline diff`: the semantic difference of two compiled plans, not of their YAML text."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.review.diff.diff_base import rotation_angle_deg

from ...edge_helpers import rig_config, write_config, write_rig

DEMO_REWRITTEN = """\
# The demo config, rewritten: other key order, comments, quoting, flow vs block style, rpy_deg for the quaternion.
output: {segment: 'episode_000', application_id: "panda_demo", path: "out/{segment}.rrd"}
edges:
  - {child: panda_link0, parent: world, rpy_deg: [0, 0, 0], translation: [0, 0, 0.5]}
frames:
  root: "world"
robots:
  arm:
    joints:
      limits:
        on_violation: error
        slack: {length: 2 mm, angle: "2 deg"}
      hold: {}
      map:
        finger:
          unit: mm
          joint: panda_finger_joint1
        j7: panda_joint7
        j6: panda_joint6
        j5: {joint: panda_joint5}
        j4: panda_joint4
        j3: {offset: 0.1, joint: panda_joint3}
        j2: {sign: -1, joint: "panda_joint2"}
        j1: panda_joint1
      unit: deg
      source: arm_state
    collision_geometries: drop
    package_paths:
      example-robot-data: ./robots/share/example-robot-data
    urdf: ./robots/panda.urdf
sources:
  arm_state:
    names:
      - j1
      - j2
      - j3
      - j4
      - j5
      - j6
      - j7
      - finger
    index: frame_index
    column: "observation.state"
    parquet: data/episode_000.parquet
version: 1
"""


def _git(folder: Path, *args: str) -> None:
    subprocess.run(
        ["git", "-c", "user.name=test", "-c", "user.email=test@example.com", "-c", "commit.gpgsign=false", *args],
        cwd=folder,
        check=True,
        capture_output=True,
    )


@pytest.fixture
def workspace(examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder of its own holding the example configs, whose robots/ and data/ are the session's examples."""
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))  # tmp_path is in no git repository
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))  # robots/ and data/ link there (confine.py)
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))  # robots/ and data/ link there, outside the folder
    folder = tmp_path / "work"
    folder.mkdir()
    for name in ("robots", "data"):
        (folder / name).symlink_to(examples_dir / name, target_is_directory=True)
    for config in ("demo.yaml", "bimanual_pandas.yaml"):
        shutil.copy(examples_dir / config, folder / config)
    return folder


def _variant(workspace: Path, name: str, old: str, new: str, config: str = "demo.yaml") -> Path:
    text = (workspace / config).read_text()
    assert old in text, old
    path = workspace / name
    path.write_text(text.replace(old, new))
    return path


def test_an_equivalent_rewrite_prints_nothing(run_cli, workspace: Path) -> None:
    rewritten = workspace / "rewritten.yaml"
    rewritten.write_text(DEMO_REWRITTEN)
    result = run_cli("diff", str(workspace / "demo.yaml"), str(rewritten), "--exit-code")
    assert (result.code, result.out, result.err) == (0, "", "")


def test_rpy_deg_rpy_and_the_same_quaternion_are_equivalent(run_cli, workspace: Path) -> None:
    half = 0.5**0.5
    text = (workspace / "bimanual_pandas.yaml").read_text()
    text = text.replace("rpy_deg: [0, 0, -90]", f"quaternion_xyzw: [0, 0, {-half!r}, {half!r}]")
    text = text.replace("rpy_deg: [0, 0, 90]", "rpy: [0, 0, 1.5707963267948966]")
    rewritten = workspace / "bimanual_rewritten.yaml"
    rewritten.write_text(text)
    result = run_cli("diff", str(workspace / "bimanual_pandas.yaml"), str(rewritten), "--exit-code")
    assert (result.code, result.out) == (0, "")


def test_a_config_moved_with_its_inputs_is_equivalent(run_cli, examples_dir: Path, workspace: Path) -> None:
    result = run_cli("diff", str(examples_dir / "demo.yaml"), str(workspace / "demo.yaml"))
    assert (result.code, result.out) == (0, "")


def test_a_sign_flip_names_the_joint(run_cli, workspace: Path) -> None:
    flipped = _variant(workspace, "flipped.yaml", "j2: {joint: panda_joint2, sign: -1}", "j2: panda_joint2")
    result = run_cli("diff", str(workspace / "demo.yaml"), str(flipped))
    assert (result.code, result.out) == (0, "robot arm: j2 -> panda_joint2: sign -1 -> 1\n")
    assert run_cli("diff", str(workspace / "demo.yaml"), str(flipped), "--exit-code").code == 1


def test_an_edge_moved_by_5_mm(run_cli, workspace: Path) -> None:
    moved = _variant(workspace, "moved.yaml", "translation: [0.0, 0.0, 0.5]", "translation: [0.0, 0.0, 0.505]")
    result = run_cli("diff", str(workspace / "demo.yaml"), str(moved))
    assert result.out == "edge world -> panda_link0: moved 5.0 mm, 0.00 deg (translation [0, 0, 0.5] -> [0, 0, 0.505])\n"


def test_an_edge_rotated(run_cli, workspace: Path) -> None:
    rotated = _variant(workspace, "rotated.yaml", "rpy_deg: [0, 0, -90]", "rpy_deg: [0, 0, -80]", config="bimanual_pandas.yaml")
    result = run_cli("diff", str(workspace / "bimanual_pandas.yaml"), str(rotated))
    assert result.out.startswith("edge world -> left_panda_link0: moved 0.0 mm, 10.00 deg (quaternion_xyzw [0, 0, -0.707106781, ")
    assert rotation_angle_deg((0, 0, 0, 1), (0, 0, 1, 0)) == pytest.approx(180)


def test_edge_kinds_fixed_chains_and_temporal_edges(run_cli, tmp_path: Path) -> None:
    folder = tmp_path / "rig"
    write_rig(folder)
    write_joint_parquet(folder / "data" / "rig.parquet", np.zeros((5, 1)))
    write_joint_parquet(folder / "data" / "pose.parquet", np.tile([0, 0, 0, 0, 0, 0, 1.0], (5, 1)), column="pose")

    def config(name: str, chain_to: str, translation: list[str], table: dict | None) -> Path:
        temporal = {"parent": "world", "child": "rig_base", "source": "base_pose", "translation": translation}
        chain = {"parent": "rig_flange", "child": "cam_copy", "fixed_chain": {"from": "rig_flange", "to": chain_to}}
        cup = {"parent": "table", "child": "cup", "translation": [0.1, 0.2, 0.0], "rpy_deg": [0, 0, 30]}
        edges = [{**temporal, "quaternion_xyzw": ["qx", "qy", "qz", "qw"]}, chain, cup, *([table] if table else [])]
        data = rig_config("rig", "data/rig.parquet", edges, frame_prefix="rig_")
        names = ["x", "y", "z", "qx", "qy", "qz", "qw"]
        data["sources"]["base_pose"] = {"parquet": "data/pose.parquet", "column": "pose", "index": "frame_index", "names": names}
        if table is None:
            data["frames"]["assume_identity"] = ["table"]
        return write_config(folder, name, data)

    old = config("old", "rig_cam", ["x", "y", "z"], None)
    new = config(
        "new", "rig_adapter", ["y", "x", "z"], {"parent": "world", "child": "table", "translation": [0, 0, 0.75], "rpy": [0, 0, 0]}
    )
    result = run_cli("diff", str(old), str(new))
    assert (result.code, result.err) == (0, "")
    lines = result.out.splitlines()
    assert lines[:2] == [
        "edge rig_flange -> cam_copy: fixed_chain to rig_cam -> rig_adapter",
        "edge rig_flange -> cam_copy: fixed_chain joints [flange_to_adapter, adapter_to_cam] -> [flange_to_adapter]",
    ]
    assert lines[2].startswith("edge rig_flange -> cam_copy: moved ")
    assert lines[3:] == [
        "edge world -> table: kind assume_identity -> static",
        "edge world -> table: moved 750.0 mm, 0.00 deg (translation [0, 0, 0] -> [0, 0, 0.75])",
        "temporal edge world -> rig_base: translation [x, y, z] -> [y, x, z]",
    ]


def test_joints_remapped(run_cli, workspace: Path) -> None:
    text = (
        (workspace / "demo.yaml")
        .read_text()
        .replace("j4: panda_joint4", "j4: panda_jointX")
        .replace("j5: panda_joint5", "j5: panda_joint4")
    )
    swapped = workspace / "swapped.yaml"
    swapped.write_text(text.replace("panda_jointX", "panda_joint5"))
    result = run_cli("diff", str(workspace / "demo.yaml"), str(swapped))
    assert result.out.splitlines() == [
        "robot arm: j4: remapped panda_joint4 -> panda_joint5",
        "robot arm: j5: remapped panda_joint5 -> panda_joint4",
    ]


def test_robot_limits_sources_and_output_changes(run_cli, workspace: Path) -> None:
    text = (workspace / "demo.yaml").read_text()
    for old, new in [
        (
            "limits: {slack: {angle: 2 deg, length: 2 mm}, on_violation: error}",
            "limits: {slack: {angle: 1 deg, length: 2 mm}, on_violation: clamp}\n      nan: hold_last",
        ),
        ("j3: {joint: panda_joint3, offset: 0.1}", "j3: {joint: panda_joint3, offset: 0.2, scale: 2}"),
        ("j6: panda_joint6", "j6: {joint: panda_joint6, wrap: 360}"),
        ("finger: {joint: panda_finger_joint1, unit: mm}", "finger: {joint: panda_finger_joint1, unit: m}"),
        ("        j7: panda_joint7\n", ""),
        ("ignore: []", "ignore: [j7]"),
        ("hold: {}", "hold: {panda_joint7: 0.0}"),
        ('frame_prefix: ""', "frame_prefix: robot_"),
        ("child: panda_link0", "child: robot_panda_link0"),
        ("application_id: panda_demo", "application_id: panda_review"),
        ("path: out/{segment}.rrd", "path: out2/{segment}.rrd"),
    ]:
        assert old in text, old
        text = text.replace(old, new)
    changed = workspace / "changed.yaml"
    changed.write_text(text)
    result = run_cli("diff", str(workspace / "demo.yaml"), str(changed))
    assert result.code == 0, result.err
    assert result.out.splitlines() == [
        'robot arm: frame_prefix "" -> robot_',
        "robot arm: NaN policy error -> hold_last",
        "robot arm: limits slack {angle: 2 deg, length: 2 mm} -> {angle: 1 deg, length: 2 mm}",
        "robot arm: limits on_violation error -> clamp",
        "robot arm: j3 -> panda_joint3: scale 1 -> 2",
        "robot arm: j3 -> panda_joint3: offset 0.1 -> 0.2",
        "robot arm: j3 -> panda_joint3: limits (source units) [-171.733, 160.273] -> [-88.7311, 77.272]",
        "robot arm: j6 -> panda_joint6: wrap none -> 360",
        "robot arm: j7 -> panda_joint7: removed (now ignored)",
        "robot arm: finger -> panda_finger_joint1: unit mm -> m",
        "robot arm: finger -> panda_finger_joint1: limits (source units) [0, 40] -> [0, 0.04]",
        "robot arm: hold panda_joint7 = 0: added",
        "edge world -> panda_link0: removed (was static, translation [0, 0, 0.5], quaternion_xyzw [0, 0, 0, 1])",
        "edge world -> robot_panda_link0: added (static, translation [0, 0, 0.5], quaternion_xyzw [0, 0, 0, 1])",
        "output: application_id panda_demo -> panda_review",
        "output: manifest out/demo.manifest.json -> out2/changed.manifest.json",
        "output: path out/episode_000.rrd -> out2/episode_000.rrd",
    ]


def test_holds_and_ignores(run_cli, workspace: Path) -> None:
    text = (workspace / "demo.yaml").read_text()
    held = (
        text.replace("        j7: panda_joint7\n", "")
        .replace("ignore: []", "ignore: [j7]")
        .replace("hold: {}", "hold: {panda_joint7: 0.25}")
    )
    (workspace / "held.yaml").write_text(held)
    (workspace / "held2.yaml").write_text(held.replace("panda_joint7: 0.25", "panda_joint7: 0.5"))
    result = run_cli("diff", str(workspace / "demo.yaml"), str(workspace / "held.yaml"))
    assert result.out.splitlines() == [
        "robot arm: j7 -> panda_joint7: removed (now ignored)",
        "robot arm: hold panda_joint7 = 0.25: added",
    ]
    result = run_cli("diff", str(workspace / "held.yaml"), str(workspace / "held2.yaml"))
    assert result.out == "robot arm: hold panda_joint7 0.25 -> 0.5\n"


def test_a_changed_urdf(run_cli, workspace: Path) -> None:
    urdf = (workspace / "robots" / "panda.urdf").read_text()
    changed = urdf.replace('name="panda_hand_joint"', 'name="panda_hand_mount"').replace(
        'lower="-3.0718" upper="-0.0698"', 'lower="-3.1" upper="-0.0698"'
    )
    assert changed.count("panda_hand_mount") == 1 and 'lower="-3.1"' in changed
    (workspace / "panda_v2.urdf").write_text(changed)
    config = _variant(workspace, "v2.yaml", "urdf: robots/panda.urdf", "urdf: panda_v2.urdf")
    result = run_cli("diff", str(workspace / "demo.yaml"), str(config))
    lines = result.out.splitlines()
    assert lines[0].startswith("robot arm: URDF file ") and lines[0].endswith("robots/panda.urdf -> panda_v2.urdf")  # robots/ is a symlink
    assert lines[1].startswith("robot arm: URDF sha256 ")
    assert lines[2:] == [
        "robot arm: URDF joints added: panda_hand_mount",
        "robot arm: URDF joints removed: panda_hand_joint",
        "robot arm: URDF joint panda_joint4: limits [-3.0718, -0.0698] -> [-3.1, -0.0698]",
        "robot arm: j4 -> panda_joint4: limits (source units) [-176.001, -3.99925] -> [-177.617, -3.99925]",
    ]


def test_json_format(run_cli, workspace: Path) -> None:
    flipped = _variant(workspace, "flipped.yaml", "j2: {joint: panda_joint2, sign: -1}", "j2: panda_joint2")
    report = json.loads(run_cli("diff", str(workspace / "demo.yaml"), str(flipped), "--format", "json").out)
    assert report["equivalent"] is False
    assert report["changes"] == [
        {
            "group": "robot",
            "subject": "robot arm",
            "detail": "j2 -> panda_joint2: sign -1 -> 1",
            "old": -1.0,
            "new": 1.0,
            "line": "robot arm: j2 -> panda_joint2: sign -1 -> 1",
        }
    ]
    same = json.loads(run_cli("diff", str(workspace / "demo.yaml"), str(workspace / "demo.yaml"), "--format", "json").out)
    assert same["equivalent"] is True and same["changes"] == []


def test_errors_in_either_config_are_user_errors(run_cli, workspace: Path) -> None:
    broken = _variant(workspace, "broken.yaml", "j2: {joint: panda_joint2, sign: -1}", "j2: {joint: panda_joint22, sign: -1}")
    result = run_cli("diff", str(workspace / "demo.yaml"), str(broken))
    assert result.code == 1 and result.out == ""
    assert result.err.startswith(f"error: {broken}:") and "panda_joint22" in result.err
    assert run_cli("diff", str(broken), str(workspace / "demo.yaml")).code == 1


def test_usage_needs_two_configs_or_git(run_cli, workspace: Path) -> None:
    assert run_cli("diff", str(workspace / "demo.yaml")).code == 2
    assert run_cli("diff", str(workspace / "demo.yaml"), str(workspace / "demo.yaml"), "--git", "HEAD").code == 2


def test_git_revision_against_the_working_tree(run_cli, workspace: Path) -> None:
    _git(workspace, "init", "-q")
    _git(workspace, "add", "demo.yaml", "robots", "data")
    _git(workspace, "commit", "-q", "-m", "demo")
    config = workspace / "demo.yaml"
    assert run_cli("diff", str(config), "--git", "HEAD", "--exit-code") == run_cli("diff", str(config), "--git", "HEAD")
    result = run_cli("diff", str(config), "--git", "HEAD", "--exit-code")
    assert (result.code, result.out) == (0, "")  # the hidden copy's name changes nothing (not even the manifest's)

    config.write_text(config.read_text().replace("j2: {joint: panda_joint2, sign: -1}", "j2: panda_joint2"))
    result = run_cli("diff", str(config), "--git", "HEAD", "--exit-code")
    assert (result.code, result.out) == (1, "robot arm: j2 -> panda_joint2: sign -1 -> 1\n")
    assert sorted(p.name for p in workspace.iterdir() if p.name.startswith(".demo")) == []  # the copy is removed

    (workspace / "new.yaml").write_text(config.read_text())
    result = run_cli("diff", str(workspace / "new.yaml"), "--git", "HEAD")
    assert result.code == 1 and "cannot read new.yaml at git revision 'HEAD'" in result.err


def test_git_errors_name_the_revision(run_cli, workspace: Path) -> None:
    config = workspace / "demo.yaml"
    result = run_cli("diff", str(config), "--git", "HEAD")
    assert result.code == 1 and "--git 'HEAD' names no commit in" in result.err and "not a git repository" in result.err

    _git(workspace, "init", "-q")
    broken = config.read_text().replace("j2: {joint: panda_joint2, sign: -1}", "j2: {joint: panda_joint22, sign: -1}")
    (workspace / "broken.yaml").write_text(broken)
    _git(workspace, "add", "broken.yaml")
    _git(workspace, "commit", "-q", "-m", "broken")
    (workspace / "broken.yaml").write_text(config.read_text())
    result = run_cli("diff", str(workspace / "broken.yaml"), "--git", "HEAD")
    assert result.code == 1 and result.err.startswith(f"error: {workspace / 'broken.yaml'}@HEAD:")
    assert not [p for p in workspace.iterdir() if p.name.startswith(".broken")]


def test_a_huge_config_at_the_revision_is_refused_as_in_the_working_tree(run_cli, workspace: Path) -> None:
    """The old text is copied only up to one byte past what the YAML reader takes, which then refuses it by its size."""
    from urdf_pipeline.config import MAX_BYTES

    config = workspace / "demo.yaml"
    _git(workspace, "init", "-q")
    config.write_text(config.read_text() + "# padding\n" * (MAX_BYTES // 10 + 1))
    _git(workspace, "add", "demo.yaml")
    _git(workspace, "commit", "-q", "-m", "huge")
    config.write_text(config.read_text()[: -10 * (MAX_BYTES // 10 + 1)])
    result = run_cli("diff", str(config), "--git", "HEAD")
    assert result.code == 1 and "is larger than 4 MB" in result.err, result.err
    assert not [p for p in workspace.iterdir() if p.name.startswith(".demo")]


@pytest.mark.parametrize(
    "revision", ["--output={pwned}", "-n", "-c core.pager=touch {pwned}", "--no-such-rev", "HEAD~5", "nope", "HEAD:demo.yaml"]
)
def test_a_revision_never_reaches_git_as_an_option(run_cli, workspace: Path, revision: str) -> None:
    """`--git REV` is verified as a commit (`rev-parse --verify --end-of-options REV^{commit}`) before any other git call:
    what a workflow passes from a pull request is a revision or a user error naming it, never an option."""
    _git(workspace, "init", "-q")
    _git(workspace, "add", "demo.yaml")
    _git(workspace, "commit", "-q", "-m", "demo")
    pwned = workspace.parent / "pwned"
    revision = revision.format(pwned=pwned)
    result = run_cli("diff", str(workspace / "demo.yaml"), f"--git={revision}")
    assert result.code == 1 and result.out == "" and not pwned.exists()
    assert f"--git '{revision}' names no commit in " in result.err and len(result.err.splitlines()) == 1


def test_a_revision_with_control_characters_is_shown_escaped(run_cli, workspace: Path) -> None:
    _git(workspace, "init", "-q")
    result = run_cli("diff", str(workspace / "demo.yaml"), "--git", "x\n::error::forged\x1b[2J")
    assert result.code == 1 and "--git 'x\\n::error::forged\\x1b[2J' names no commit" in result.err and len(result.err.splitlines()) == 1


def test_the_config_at_a_revision_is_read_by_its_commit(run_cli, workspace: Path) -> None:
    """A tag named like an option resolves as a revision; the config's text at it is compared."""
    _git(workspace, "init", "-q")
    _git(workspace, "add", "demo.yaml", "robots", "data")
    _git(workspace, "commit", "-q", "-m", "demo")
    _git(workspace, "tag", "v1")
    config = workspace / "demo.yaml"
    config.write_text(config.read_text().replace("j2: {joint: panda_joint2, sign: -1}", "j2: panda_joint2"))
    result = run_cli("diff", str(config), "--git", "v1^{commit}")
    assert (result.code, result.out) == (0, "robot arm: j2 -> panda_joint2: sign -1 -> 1\n")


def test_the_joint_series_option_turned_on(run_cli, workspace: Path) -> None:
    text = (workspace / "demo.yaml").read_text()
    series = _variant(workspace, "series.yaml", "  application_id: panda_demo\n", "  application_id: panda_demo\n  joint_series: true\n")
    (workspace / "series_off.yaml").write_text(series.read_text().replace("joint_series: true", "joint_series: false"))
    result = run_cli("diff", str(workspace / "demo.yaml"), str(series))
    assert (result.code, result.out) == (0, "output: joint_series false -> true\n")
    assert json.loads(run_cli("diff", str(series), str(workspace / "demo.yaml"), "--format", "json").out)["changes"][0]["old"] is True
    assert run_cli("diff", str(workspace / "demo.yaml"), str(workspace / "series_off.yaml"), "--exit-code").code == 0  # the default
    assert "joint_series" not in text


def test_the_qa_section_is_in_plans_json_and_diff_says_its_changes(run_cli, workspace: Path) -> None:
    """A plan field added in the report's two places (CONTRIBUTING.md): `plan` prints it, `diff` compares it, with no
    code of diff's own; a config at the defaults shows no `qa` at all (the golden files keep their bytes)."""
    strict = _variant(workspace, "strict.yaml", "version: 1\n", 'version: 1\nqa: {spike: {factor: 10}, gap: "50 ms", fail_on: [spike]}\n')
    stricter = _variant(
        workspace, "stricter.yaml", "version: 1\n", 'version: 1\nqa: {spike: {factor: 15}, gap: "3 steps", fail_on: [spike]}\n'
    )
    shown = json.loads(run_cli("plan", str(strict), "--format", "json").out)["qa"]
    assert (shown["spike_factor"], shown["gap"], shown["fail_on"]) == (10.0, "50 ms", ["spike"])
    assert "qa" not in json.loads(run_cli("plan", str(workspace / "demo.yaml"), "--format", "json").out)
    result = run_cli("diff", str(strict), str(stricter))
    assert (result.code, result.out) == (0, "plan: qa spike_factor 10 -> 15\nplan: qa gap 50 ms -> 3 steps\n")

"""Units by joint kind, and one meaning of "limits in source units": plan, check and the run print the same numbers."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from urdf_pipeline.errors import closest, did_you_mean
from urdf_pipeline.examples import write_joint_parquet

# A robot with both joint kinds: a revolute elbow in [-1, 2] rad and a prismatic slider in [0, 0.05] m.
TWO_KINDS_URDF = """<?xml version="1.0"?>
<robot name="two_kinds">
  <link name="base"/>
  <link name="upper"/>
  <link name="carriage"/>
  <joint name="elbow" type="revolute">
    <parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1.0" upper="2.0" effort="1" velocity="1"/>
  </joint>
  <joint name="slider" type="prismatic">
    <parent link="upper"/><child link="carriage"/>
    <origin xyz="0.2 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0.0" upper="0.05" effort="1" velocity="1"/>
  </joint>
</robot>
"""
DEG = math.pi / 180


def two_kinds_config(
    directory: Path, unit: Any = None, elbow: Any = "elbow", slider: Any = "slider", values: Any = None, limits: Any = None
) -> Path:
    """A config of the two-joint robot in `directory` (robot.urdf and data.parquet are written beside it)."""
    (directory / "robot.urdf").write_text(TWO_KINDS_URDF)
    raw = np.array(values if values is not None else [[0.0, 0.0]] * 10, dtype=np.float64)
    write_joint_parquet(directory / "data.parquet", raw)
    joints: dict[str, Any] = {"source": "state", "map": {"e": elbow, "s": slider}}
    if unit is not None:
        joints["unit"] = unit
    if limits is not None:
        joints["limits"] = limits
    config = {
        "version": 1,
        "sources": {"state": {"parquet": "data.parquet", "column": "observation.state", "index": "frame_index", "names": ["e", "s"]}},
        "robots": {"r": {"urdf": "robot.urdf", "joints": joints}},
        "output": {"path": "out/{segment}.rrd", "application_id": "units", "segment": "units"},
    }
    path = directory / "config.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


def plan_rows(run_cli, config: Path) -> dict[str, dict[str, Any]]:
    result = run_cli("plan", str(config), "--format", "json")
    assert result.code == 0, result.err
    (robot,) = json.loads(result.out)["robots"]
    return {row["joint"]: row for row in robot["joints"]}


@pytest.mark.parametrize(
    ("unit", "elbow_unit", "slider_unit"),
    [
        (None, "rad", "m"),  # omitted: the URDF's own unit for each joint kind
        ("deg", "deg", "m"),  # an angular unit applies to revolute and continuous joints only
        ("rad", "rad", "m"),
        ("mm", "rad", "mm"),  # a length unit to prismatic joints only
        ("cm", "rad", "cm"),
        ({"angle": "deg", "length": "mm"}, "deg", "mm"),
        ({"length": "mm"}, "rad", "mm"),
        ({"angle": "deg"}, "deg", "m"),
    ],
)
def test_robot_unit_applies_per_joint_kind(run_cli, tmp_path: Path, unit: Any, elbow_unit: str, slider_unit: str) -> None:
    rows = plan_rows(run_cli, two_kinds_config(tmp_path, unit))
    assert (rows["elbow"]["unit"], rows["slider"]["unit"]) == (elbow_unit, slider_unit)
    factor = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}[slider_unit]
    assert rows["slider"]["limits_source_units"] == pytest.approx([0.0, 0.05 / factor])


def test_a_map_entry_unit_overrides_the_robot_unit(run_cli, tmp_path: Path) -> None:
    rows = plan_rows(run_cli, two_kinds_config(tmp_path, "deg", slider={"joint": "slider", "unit": "mm"}))
    assert (rows["elbow"]["unit"], rows["slider"]["unit"]) == ("deg", "mm")
    both = {"angle": "deg", "length": "mm"}
    rows = plan_rows(
        run_cli, two_kinds_config(tmp_path, both, elbow={"joint": "elbow", "unit": "rad"}, slider={"joint": "slider", "unit": "cm"})
    )
    assert (rows["elbow"]["unit"], rows["slider"]["unit"]) == ("rad", "cm")


def test_a_map_entry_unit_of_the_other_kind_is_refused(run_cli, tmp_path: Path) -> None:
    result = run_cli("validate", str(two_kinds_config(tmp_path, slider={"joint": "slider", "unit": "deg"})))
    assert result.code == 1
    assert "joint 'slider' is prismatic (URDF unit m) but its source unit is deg (from its map entry); set unit: m, cm or mm" in result.err


def test_a_single_unit_that_applies_to_no_mapped_joint_is_refused(run_cli, tmp_path: Path) -> None:
    config = two_kinds_config(tmp_path, "mm", slider={"joint": "slider", "unit": "m"})
    result = run_cli("validate", str(config))
    assert result.code == 1 and "config.yaml:" in result.err
    assert "joints.unit mm applies to prismatic joints only" in result.err and "Write unit: rad or deg" in result.err


# --- limits in source units: one number everywhere --------------------------------------------------------------------

LIMIT_CASES = {  # elbow entry (robot unit deg) -> its limits in source units, computed here by hand
    "plain": ({"joint": "elbow"}, (-1.0 / DEG, 2.0 / DEG)),
    "sign": ({"joint": "elbow", "sign": -1}, (-2.0 / DEG, 1.0 / DEG)),
    "scale": ({"joint": "elbow", "scale": -1}, (-2.0 / DEG, 1.0 / DEG)),
    "scale_2": ({"joint": "elbow", "scale": 2}, (-0.5 / DEG, 1.0 / DEG)),
    "offset": ({"joint": "elbow", "offset": 0.5}, (-1.5 / DEG, 1.5 / DEG)),
    "sign_offset": ({"joint": "elbow", "sign": -1, "offset": 0.5}, (-1.5 / DEG, 1.5 / DEG)),
    "source_range": ({"joint": "elbow", "source_range": [0, 100]}, (0.0, 100.0)),
    "source_range_flipped": ({"joint": "elbow", "source_range": [100, 0]}, (0.0, 100.0)),
    "joint_range": ({"joint": "elbow", "source_range": [0, 100], "joint_range": [-0.5, 1.5]}, (-25.0, 125.0)),
}
NUMBER = r"(-?[0-9.]+(?:e[-+]?[0-9]+)?)"


def printed_limits(run_cli, config: Path) -> dict[str, tuple[float, float]]:
    """The elbow's limits in source units as plan (text, json, markdown), check (text, json) and the run's error print them."""
    found: dict[str, tuple[float, float]] = {}
    text = run_cli("plan", str(config)).out
    found["plan text"] = _pair(re.search(rf"e\[0\] -> elbow: .*limits {NUMBER} \.\. {NUMBER} ", text), text)
    rows = plan_rows(run_cli, config)
    found["plan json"] = tuple(rows["elbow"]["limits_source_units"])  # type: ignore[assignment]
    markdown = run_cli("plan", str(config), "--format", "markdown").out
    row = next(line for line in markdown.splitlines() if "elbow" in line and line.startswith("|"))
    found["plan markdown"] = _pair(re.search(rf"\| {NUMBER} \.\. {NUMBER}", row), row)
    check = run_cli("check", str(config))
    found["check text"] = _pair(re.search(rf"e -> elbow .*URDF limits {NUMBER} \.\. {NUMBER};", check.out), check.out)
    (report, _) = json.loads(run_cli("check", str(config), "--format", "json").out)
    found["check json"] = tuple(report["limits_in_source_unit"])  # type: ignore[assignment]
    run = run_cli("run", str(config))
    assert run.code == 1, run.err
    found["run error"] = _pair(re.search(rf"joint 'elbow' .* beyond the URDF limits \[{NUMBER}, {NUMBER}\]", run.err), run.err)
    return found


def _pair(match: re.Match[str] | None, text: str) -> tuple[float, float]:
    assert match is not None, text
    return float(match.group(1)), float(match.group(2))


@pytest.mark.parametrize("case", sorted(LIMIT_CASES))
def test_plan_check_and_run_print_the_same_limits(run_cli, tmp_path: Path, case: str) -> None:
    entry, expected = LIMIT_CASES[case]
    beyond = expected[1] + 10 * (expected[1] - expected[0])  # far above the limits whatever the direction of the map
    config = two_kinds_config(tmp_path, {"angle": "deg"}, elbow=entry, values=[[beyond, 0.0]] * 10)
    found = printed_limits(run_cli, config)
    for where, (low, high) in found.items():
        assert low <= high, where
        assert (low, high) == pytest.approx(expected, rel=1e-5, abs=1e-9), where


def test_the_demo_j3_limits_agree(run_cli, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The demo's j3 (deg, offset 0.1 rad): -171.733 .. 160.273 deg in plan, check and the run's error alike."""
    folder = tmp_path / "demo"
    folder.mkdir()
    shutil.copy(examples_dir / "demo.yaml", folder / "demo.yaml")
    (folder / "robots").symlink_to(examples_dir / "robots", target_is_directory=True)
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    raw = np.zeros((10, 8))
    raw[:, 3] = -90.0  # j4's limits exclude 0
    raw[:, 2] = 170.0  # within -166..166 (the URDF limits / unit factor) but beyond 160.273 once the offset is added
    write_joint_parquet(folder / "data" / "episode_000.parquet", raw)
    config = folder / "demo.yaml"
    expected = ((-2.8973 - 0.1) / DEG, (2.8973 - 0.1) / DEG)
    text = run_cli("plan", str(config)).out
    assert _pair(re.search(rf"j3\[2\] -> panda_joint3: .*limits {NUMBER} \.\. {NUMBER} deg", text), text) == pytest.approx(
        expected, rel=1e-5
    )
    rows = plan_rows(run_cli, config)
    assert rows["panda_joint3"]["limits_source_units"] == pytest.approx(expected)
    (report,) = [r for r in json.loads(run_cli("check", str(config), "--format", "json").out) if r["joint"] == "panda_joint3"]
    assert report["limits_in_source_unit"] == pytest.approx(expected) and not report["current_fits"]
    run = run_cli("run", str(config))
    assert run.code == 1
    match = re.search(rf"joint 'panda_joint3' .* beyond the URDF limits \[{NUMBER}, {NUMBER}\] deg", run.err)
    assert _pair(match, run.err) == pytest.approx(expected, rel=1e-5)


# --- limits.slack carries its own unit ---------------------------------------------------------------------------------


@pytest.mark.parametrize("unit", ["deg", "rad", {"angle": "deg", "length": "mm"}, {"angle": "rad", "length": "cm"}])
def test_slack_keeps_its_meaning_when_the_unit_changes(run_cli, tmp_path: Path, unit: Any) -> None:
    """Switching deg to rad once turned `slack: 2` from 2 deg into 2 rad (115 deg); now 2 deg stays 2 deg."""
    rows = plan_rows(run_cli, two_kinds_config(tmp_path, unit, limits={"slack": {"angle": "2 deg", "length": "5 mm"}}))
    assert rows["elbow"]["slack"] == {"value": 2.0, "unit": "deg"} and rows["slider"]["slack"] == {"value": 5.0, "unit": "mm"}
    angle_unit = rows["elbow"]["unit"]
    assert rows["elbow"]["slack_source_units"] == pytest.approx(2.0 if angle_unit == "deg" else 2 * DEG)
    length_factor = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}[rows["slider"]["unit"]]
    assert rows["slider"]["slack_source_units"] == pytest.approx(0.005 / length_factor)


@pytest.mark.parametrize(
    ("slack", "elbow", "slider"),
    [
        ("2 deg", {"value": 2.0, "unit": "deg"}, {"value": 0.0, "unit": "m"}),  # one kind: the other gets none
        ("5 mm", {"value": 0.0, "unit": "rad"}, {"value": 5.0, "unit": "mm"}),
        ("0.01 rad", {"value": 0.01, "unit": "rad"}, {"value": 0.0, "unit": "m"}),
        (0, {"value": 0.0, "unit": "rad"}, {"value": 0.0, "unit": "m"}),  # a bare zero needs no unit
        ({"length": "1 cm"}, {"value": 0.0, "unit": "rad"}, {"value": 1.0, "unit": "cm"}),
    ],
)
def test_slack_applies_to_the_joints_of_its_kind(run_cli, tmp_path: Path, slack: Any, elbow: dict, slider: dict) -> None:
    rows = plan_rows(run_cli, two_kinds_config(tmp_path, "deg", limits={"slack": slack}))
    assert rows["elbow"]["slack"] == elbow and rows["slider"]["slack"] == slider


def test_diff_shows_no_slack_change_when_only_the_unit_changes(run_cli, tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    old = two_kinds_config(tmp_path / "a", "deg", limits={"slack": "2 deg"})
    new = two_kinds_config(tmp_path / "b", "rad", limits={"slack": "2 deg"})
    result = run_cli("diff", str(old), str(new))
    assert result.code == 0 and "unit deg -> rad" in result.out and "slack" not in result.out, result.out
    newer = two_kinds_config(tmp_path / "b", "rad", limits={"slack": "1 deg"})
    assert "robot r: limits slack 2 deg -> 1 deg" in run_cli("diff", str(old), str(newer)).out


def test_plan_text_shows_the_slack_with_its_unit(run_cli, tmp_path: Path) -> None:
    config = two_kinds_config(tmp_path, "rad", limits={"slack": {"angle": "2 deg", "length": "5 mm"}})
    text = run_cli("plan", str(config)).out
    assert re.search(r"e\[0\] -> elbow: .*limits -1 \.\. 2 rad, slack 2 deg$", text, re.M), text
    assert re.search(r"s\[1\] -> slider: .*limits 0 \.\. 0\.05 m, slack 5 mm$", text, re.M), text


def test_a_bare_slack_names_what_it_meant_with_the_configs_units(run_cli, tmp_path: Path) -> None:
    config = two_kinds_config(tmp_path, {"angle": "deg", "length": "mm"}, limits={"slack": 1.5})
    result = run_cli("validate", "--no-data", str(config))
    assert result.code == 1 and len(result.err.splitlines()) == 1
    assert re.match(r"error: .*config\.yaml:\d+:\d+: robots\.r\.joints\.limits\.slack: 1\.5 has no unit", result.err)
    assert "write slack: {angle: 1.5 deg, length: 1.5 mm} (what 1.5 meant with angles in deg and lengths in mm)" in result.err


def test_a_run_refused_for_degrees_configured_as_radians_names_the_unit(run_cli, tmp_path: Path) -> None:
    """LeRobot SO-100/SO-101 data is in degrees: a config left at rad is refused with the unit that fits, one located
    line, nothing written."""
    config = two_kinds_config(tmp_path, "rad", values=[[float(v), 0.01] for v in np.linspace(-50, 100, 20)])
    result = run_cli("run", str(config))
    assert result.code == 1 and not result.out.strip()
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    assert len(errors) == 1, result.err
    assert re.match(rf"error: {re.escape(str(config))}:\d+:\d+: robots\.r\.joints\.map\.e: ", errors[0]), errors[0]
    assert "the values fit the limits if they are degrees: `unit: deg` on this entry" in errors[0]
    assert not [p for p in (tmp_path / "out").rglob("*") if p.is_file()]  # nothing written, not even a partial file


def test_a_run_refused_for_mm_configured_as_metres_names_the_unit(run_cli, tmp_path: Path) -> None:
    config = two_kinds_config(tmp_path, values=[[0.0, float(v)] for v in np.linspace(0, 40, 20)])
    result = run_cli("run", str(config))
    assert result.code == 1
    assert "joint 'slider'" in result.err and "the values fit the limits if they are millimetres: `unit: mm`" in result.err
    assert not [p for p in (tmp_path / "out").rglob("*") if p.is_file()]  # nothing written, not even a partial file


def test_a_run_refused_with_values_no_unit_explains_says_nothing_of_units(run_cli, tmp_path: Path) -> None:
    config = two_kinds_config(tmp_path, "deg", values=[[v, 0.0] for v in (-5000.0, 5000.0)])  # no unit puts +-5000 within -1..2 rad
    result = run_cli("run", str(config))
    assert result.code == 1 and "Check this entry's joint, unit, sign and offset" in result.err and "fit the limits if" not in result.err


# --- did you mean ------------------------------------------------------------------------------------------------------


def test_did_you_mean_suggests_a_typo() -> None:
    assert closest("panda_jiont1", ["panda_joint1", "panda_joint2", "panda_finger_joint1"]) == "panda_joint1"
    assert did_you_mean("Wrist_Rol", ["wrist_roll", "wrist_pitch"]) == " (did you mean 'wrist_roll'?)"


def test_did_you_mean_is_silent_for_a_far_name() -> None:
    assert closest("shoulder_pan", ["shoulder_lift", "elbow_flex"]) is None  # another joint, not a typo (ratio 0.72)
    assert did_you_mean("gripper", ["panda_finger_joint1", "panda_joint7"]) == ""


def test_a_far_joint_name_in_the_map_gets_no_suggestion(run_cli, tmp_path: Path) -> None:
    result = run_cli("validate", str(two_kinds_config(tmp_path, slider="shoulder_lift")))
    assert result.code == 1 and "URDF 'two_kinds' has no joint 'shoulder_lift'" in result.err and "did you mean" not in result.err
    result = run_cli("validate", str(two_kinds_config(tmp_path, slider="slidr")))
    assert "URDF 'two_kinds' has no joint 'slidr' (did you mean 'slider'?)" in result.err

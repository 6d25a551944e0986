"""`urdf-pipeline check`: candidate corrections per joint, verdicts, the YAML to paste, JSON and exit status."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.compile import unit_hint
from urdf_pipeline.confine import ALLOW_ENV
from urdf_pipeline.errors import Where
from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.plan import JointChannel
from urdf_pipeline.review.check.check_candidates import fitting
from urdf_pipeline.review.check.check_joints import check_channel

from ...conftest import SHARED

HERE = Where(Path("c.yaml"), 1)


def revolute(lower_deg: float, upper_deg: float, slack_deg: float = 0.0, sign: float = 1.0, unit: str = "deg") -> JointChannel:
    f = math.pi / 180
    return JointChannel("j", "s", 0, unit, f if unit == "deg" else 1.0, sign, 0.0, lower_deg * f, upper_deg * f, slack_deg * f, HERE)


def prismatic(unit: str, lower: float = 0.0, upper: float = 0.04) -> JointChannel:
    return JointChannel("finger", "f", 0, unit, {"m": 1.0, "cm": 1e-2, "mm": 1e-3}[unit], 1.0, 0.0, lower, upper, 0.0, HERE)


def report(channel: JointChannel, values) -> object:
    return check_channel(type("R", (), {"key": "arm"})(), channel, np.asarray(values, dtype=float))


@pytest.mark.parametrize(
    ("channel", "values", "unit"),
    [
        (revolute(-166, 166, unit="rad"), np.linspace(-150, 160, 40), "deg"),
        (prismatic("m"), np.linspace(0, 40, 40), "mm"),
        (prismatic("m"), np.linspace(0, 4, 40), "cm"),  # fits in cm and in mm: the bigger unit first, both ways
        (revolute(-1, 215, unit="rad"), np.linspace(-200, -10, 40), None),  # negated degrees: no unit alone fits
        (revolute(-1, 215), np.linspace(-200, -10, 40), None),
    ],
)
def test_runs_unit_hint_and_checks_top_candidate_agree(channel: JointChannel, values: np.ndarray, unit: str | None) -> None:
    """One advisor (compile/units.py): run's refusal names the unit check's simplest fitting correction changes alone."""
    hinted = re.search(r"`unit: (\w+)`", unit_hint(channel, float(values.min()), float(values.max())))
    top = fitting(channel, values)[0]
    assert (hinted[1] if hinted else None) == unit
    assert (top.unit if top.changes(channel) == ("unit",) else None) == unit


def test_a_single_fitting_correction_gives_the_yaml_to_paste() -> None:
    r = report(revolute(-1, 215), np.linspace(-200, -10, 50))  # panda_joint6-like limits, logged negated
    assert r.verdict == "fits" and not r.current_fits
    assert r.paste == "s: {joint: j, unit: deg, sign: -1}"


def test_the_configs_own_corrections_that_fit_say_fits_as_configured() -> None:
    r = report(revolute(-166, 166), np.linspace(-30, 30, 50))  # negated fits too: not "ambiguous" for a config that fits
    assert r.verdict == "fits" and r.message == "fits as configured" and r.current_fits and r.paste is None
    assert r.fitting[0] == "identity (the config's)" and "negate" in r.fitting


def test_several_equally_simple_corrections_are_ambiguous() -> None:
    r = report(revolute(-166, 166), np.linspace(200, 300, 50))  # wrapped by a turn, or offset by -180 deg: one change each
    assert r.verdict == "ambiguous" and not r.current_fits and r.paste is None
    assert "wrap a full turn" in r.message and "offset -180 deg" in r.message and "settle against a known pose" in r.message


def test_a_servo_reporting_a_full_turn_needs_wrap() -> None:
    r = report(revolute(-166, 166), np.linspace(200, 300, 50))
    assert not r.current_fits and any("wrap a full turn" in f for f in r.fitting)


def test_no_fitting_correction_points_at_the_mapping() -> None:
    r = report(revolute(-90, 90), np.linspace(0, 400, 50))
    assert r.verdict == "none" and "probably another joint" in r.message


def test_overshoot_within_slack_is_reported_as_calibration_slack() -> None:
    r = report(revolute(-90, 90, slack_deg=2.0), [0.0, 91.0, 91.5])
    assert r.current_fits and r.slack_rows == 2 and r.slack_worst == 91.5


def test_prismatic_values_in_mm_declared_as_metres() -> None:
    r = report(prismatic("m"), np.linspace(1, 39, 20))
    assert r.verdict == "fits" and r.paste == "f: {joint: finger, unit: mm}" and r.unit_fits == "mm"
    assert r.message == "the values fit if they are millimetres: `unit: mm`"


def test_prismatic_values_in_metres_declared_as_mm_fit_but_are_clearly_ambiguous() -> None:
    r = report(prismatic("mm"), np.linspace(0.001, 0.039, 20))  # as mm they barely leave zero; as metres they fill the range
    assert r.current_fits and r.verdict == "ambiguous"
    assert "fits as configured, but the values also fit if they are metres (`unit: m`)" in r.message


def test_prismatic_values_in_cm_declared_as_metres() -> None:
    r = report(prismatic("m"), np.linspace(0.5, 3.9, 20))  # cm fills the range, mm fits too (a tenth of it): cm first
    assert not r.current_fits and r.verdict == "ambiguous" and r.message.index("unit cm") < r.message.index("unit mm")


@pytest.mark.parametrize(("lower", "upper"), [(-166, 166), (-180, 180), (-110, 110)])
def test_degrees_configured_as_radians_get_the_unit_not_a_wrap_or_another_joint(lower: float, upper: float) -> None:
    """LeRobot SO-100/SO-101 data is in degrees; a config left at rad must hear so, also for limits of a full turn
    (where "wrap a full turn" would fit anything)."""
    r = report(revolute(lower, upper, unit="rad"), np.linspace(-87, 88, 200))
    assert not r.current_fits and r.verdict == "fits" and r.unit_fits == "deg"
    assert r.message.startswith("the values fit if they are degrees: `unit: deg`")
    assert r.paste == "s: {joint: j, unit: deg}"
    assert "wrap" not in r.message and "another joint" not in r.message


def test_degrees_configured_as_radians_with_a_sign_get_both() -> None:
    r = report(revolute(-1, 215, unit="rad"), np.linspace(-200, -10, 50))
    assert r.verdict == "fits" and r.paste == "s: {joint: j, unit: deg, sign: -1}" and "degrees" in r.message


def test_radians_configured_as_degrees_fit_but_are_clearly_ambiguous() -> None:
    r = report(revolute(-166, 166), np.linspace(-1.5, 2.0, 50))  # 2 deg of a 332 deg joint, or 115 deg: say so
    assert r.current_fits and r.verdict == "ambiguous"
    assert "fits as configured, but the values also fit if they are radians (`unit: rad`)" in r.message
    assert "within 2 deg of zero" in r.message and "332 deg" in r.message


def test_small_degrees_far_from_zero_are_not_suspected_of_being_radians() -> None:
    r = report(revolute(-166, 166), np.linspace(10, 40, 50))  # as radians far beyond the limits
    assert r.verdict == "fits" and r.message == "fits as configured"


def test_radians_configured_as_degrees_that_do_not_fit_name_the_unit_first() -> None:
    r = report(revolute(-176, -4), np.linspace(-2.5, -1.0, 50))  # panda_joint4: radians, or degrees offset by -90
    assert not r.current_fits and r.verdict == "ambiguous" and r.message.index("unit rad") < r.message.index("offset")


def test_a_real_joint_swap_is_still_probably_another_joint() -> None:
    swapped = np.linspace(-100, 100, 60)  # panda_joint1's values in panda_joint4's column (degrees, as configured)
    r = report(revolute(-176, -4), swapped)
    assert r.verdict == "none" and "probably another joint" in r.message
    in_rad = report(revolute(-176, -4, unit="rad"), np.radians(swapped))  # the same in radians: degrees + offset is no way out
    assert in_rad.verdict == "none" and "probably another joint" in in_rad.message


def test_the_simplest_fitting_correction_is_the_advice() -> None:
    r = report(revolute(-1, 215), np.linspace(-200, -10, 50))  # negate (1 change) beats e.g. negate and wrap
    assert r.verdict == "fits" and r.message.startswith("one correction fits: negate")


def test_cli_json_and_exit_status(examples_dir: Path, run_cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))  # the negated config reads the examples (confine.py)
    result = run_cli("check", str(examples_dir / "demo.yaml"), "--format", "json")
    assert result.code == 0, result.err
    reports = json.loads(result.out)
    assert {r["joint"] for r in reports} >= {"panda_joint1", "panda_finger_joint1"} and all(r["current_fits"] for r in reports)

    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    raw = np.zeros((30, 8))
    raw[:, 3] = -90.0
    raw[:, 5] = -np.linspace(10, 200, 30)  # j6 logged negated: the config's identity does not fit
    write_joint_parquet(tmp_path / "negated.parquet", raw)
    data["sources"]["arm_state"]["parquet"] = str(tmp_path / "negated.parquet")
    for key in ("urdf",):
        data["robots"]["arm"][key] = str(examples_dir / data["robots"]["arm"][key])
    data["robots"]["arm"]["package_paths"] = {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")}
    config = tmp_path / "negated.yaml"
    config.write_text(yaml.safe_dump(data))
    result = run_cli("check", str(config))
    assert result.code == 3
    assert "j6 -> panda_joint6 [deg]" in result.out and "DOES NOT FIT" in result.out
    assert "paste: j6: {joint: panda_joint6, unit: deg, sign: -1}" in result.out


def test_current_correction_is_marked() -> None:
    r = report(replace(revolute(-166, 166), sign=-1.0), np.linspace(-30, 30, 10))
    assert "negate (the config's)" in r.fitting


def test_source_range_values_are_checked_against_the_range() -> None:
    channel = replace(
        JointChannel("finger", "g", 0, "source units", 1.0, 1.0, 0.0, 0.021, 0.057, 0.0, HERE),
        source_range=(0.0, 1.0),
        target_range=(0.021, 0.057),
    )
    assert report(channel, [0.1, 0.9]).verdict == "fits"
    outside = report(channel, [0.1, 1.5])
    assert outside.verdict == "none" and not outside.current_fits and "source_range" in outside.message


def test_lerobot_degrees_configured_as_radians_get_the_robot_unit(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    """The SO-101 example (LeRobot, degrees) with `unit: rad`: every joint hears "degrees", never a wrap or another
    joint, and the robot hears the one line to change."""
    text = (examples_dir / "so101_lerobot.yaml").read_text()
    assert "      unit: deg\n" in text
    config = examples_dir / "so101_lerobot_in_rad.yaml"
    config.write_text(text.replace("      unit: deg\n", "      unit: rad\n"))
    result = run_cli("check", str(config))
    assert result.code == 3
    verdicts = [line.strip() for line in result.out.splitlines() if line.startswith("    fits:") or line.startswith("    ambiguous:")]
    assert len(verdicts) == 6 and all(v.startswith("fits: the values fit if they are degrees: `unit: deg`") for v in verdicts), verdicts
    assert "wrap" not in result.out and "another joint" not in result.out
    assert "  whole robot: every revolute and continuous joint of robot so101 fits if its values are degrees: " in result.out
    assert "write `unit: deg` under robots.so101.joints" in result.out
    reports = json.loads(run_cli("check", str(config), "--format", "json").out)
    assert {r["unit_fits"] for r in reports} == {"deg"} and all("unit: deg" in r["robot_advice"] for r in reports)
    assert run_cli("check", str(examples_dir / "so101_lerobot.yaml")).out.count("fits: fits as configured") == 6


G1_DATA = SHARED / "data" / "lerobot_g1_inspire_v21"
G1_CONFIG = Path(__file__).resolve().parents[2] / "configs" / "valid" / "g1_inspire_lerobot.yaml"


@pytest.mark.skipif(not G1_DATA.is_dir(), reason=f"{G1_DATA} is absent (shared data is not part of a fresh clone)")
def test_the_real_g1_recording_configured_in_degrees_hears_radians_for_the_robot(
    examples_dir: Path, run_cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The real G1 recording (radians) near its rest pose: configured as `deg`, every arm joint still fits, most barely
    leave zero. The robot hears that its joints look like radians, with the line to paste; configured as `rad`, nothing
    to say."""
    monkeypatch.setenv(ALLOW_ENV, str(G1_DATA))
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / G1_DATA.name).symlink_to(G1_DATA, target_is_directory=True)
    (tmp_path / "robots").symlink_to(examples_dir / "robots", target_is_directory=True)
    text = G1_CONFIG.read_text()
    assert "      unit: rad\n" in text
    (tmp_path / "g1.yaml").write_text(text)
    (tmp_path / "g1_deg.yaml").write_text(text.replace("      unit: rad\n", "      unit: deg\n"))
    as_rad = run_cli("check", str(tmp_path / "g1.yaml"))
    assert as_rad.code == 0 and "whole robot" not in as_rad.out and as_rad.out.count("fits: fits as configured") == 14, as_rad.out
    as_deg = run_cli("check", str(tmp_path / "g1_deg.yaml"))
    assert as_deg.code == 0, as_deg.err
    assert (
        "  whole robot: every revolute and continuous joint of robot g1 fits as configured and also if its values are radians" in as_deg.out
    )
    assert "write `unit: rad` under robots.g1.joints; settle against a known pose" in as_deg.out
    assert as_deg.out.count("ambiguous: fits as configured, but the values also fit if they are radians") >= 1


def _panda_dataset_with_episode_3_in_degrees(examples_dir: Path) -> Path:
    """Five episodes of a Panda in radians, but episode 3 logged in degrees: a unit judged on the first episode only
    looks right."""
    from ...lerobot_layouts import lerobot_panda_config, write_dataset

    rest = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0, 0.02])
    noise = np.random.default_rng(3)
    episodes = [rest + noise.normal(0, 0.002, (40, 8)) for _ in range(5)]
    episodes[3][:, :7] = np.degrees(episodes[3][:, :7])
    write_dataset(examples_dir / "data" / "check_episodes", episodes, "v2.1")
    return lerobot_panda_config(examples_dir, "check_episodes", {"lerobot": "data/check_episodes"})


def test_episode_and_spread_judge_other_segments_than_the_first(examples_dir: Path, run_cli) -> None:
    """`check` samples the first segment and says so; `--episode 3` finds episode 3's other unit and names its
    segment; `--spread` reads segments spread over the dataset (first, last, between) and names them."""
    config = str(_panda_dataset_with_episode_3_in_degrees(examples_dir))
    default = run_cli("check", config)
    assert default.code == 0 and default.out.startswith("sampled segment: episode_000000\nrobot arm: 40 sampled rows\n")
    third = run_cli("check", config, "--episode", "3")
    assert third.code == 3 and third.out.startswith("sampled segment: episode_000003\n") and "DOES NOT FIT" in third.out
    reports = json.loads(run_cli("check", config, "--episode", "3", "--format", "json").out)
    assert {tuple(r["segments"]) for r in reports} == {("episode_000003",)}
    spread = run_cli("check", config, "--spread", "3")
    assert spread.code == 0 and spread.out.startswith(
        "sampled segments: episode_000000, episode_000002, episode_000004\n"
    )  # 3 misses episode 3
    assert "robot arm: 120 sampled rows" in spread.out  # each segment's first rows, concatenated
    assert run_cli("check", config, "--spread", "9").out.startswith("sampled segments: " + ", ".join(f"episode_{i:06d}" for i in range(5)))
    spread4 = run_cli("check", config, "--spread", "4", "--format", "json")
    assert json.loads(spread4.out)[0]["segments"] == ["episode_000000", "episode_000001", "episode_000003", "episode_000004"]
    assert spread4.code == 3
    within = run_cli("check", config, "--episode", "2:5", "--spread", "2")  # spread over the episodes SPEC selects
    assert within.code == 0 and within.out.startswith("sampled segments: episode_000002, episode_000004\n")


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("9", "error: --episode: episode(s) 9 do not exist (the dataset's episodes: 0..4)"),
        ("x", "error: --episode: episodes 'x' is not all, a list of indices (0,3,7) or a range A:B (10:20)"),
        ("1:3", "error: --episode: '1:3' selects 2 segments (episode_000001, episode_000002): name one episode, or add --spread N"),
    ],
)
def test_a_bad_episode_is_one_located_error_line(examples_dir: Path, run_cli, spec: str, message: str) -> None:
    result = run_cli("check", str(_panda_dataset_with_episode_3_in_degrees(examples_dir)), "--episode", spec)
    assert result.code != 0 and result.out == ""
    assert len(result.err.strip().splitlines()) == 1 and result.err.startswith(message), result.err

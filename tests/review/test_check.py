"""`urdf-pipeline check`: candidate corrections per joint, verdicts, the YAML to paste, JSON and exit status."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.errors import Where
from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.plan import JointChannel
from urdf_pipeline.review.check import check_channel

HERE = Where(Path("c.yaml"), 1)


def revolute(lower_deg: float, upper_deg: float, slack_deg: float = 0.0, sign: float = 1.0) -> JointChannel:
    f = math.pi / 180
    return JointChannel("j", "s", 0, "deg", f, sign, 0.0, lower_deg * f, upper_deg * f, slack_deg * f, HERE)


def report(channel: JointChannel, values) -> object:
    return check_channel(type("R", (), {"key": "arm"})(), channel, np.asarray(values, dtype=float))


def test_a_single_fitting_correction_gives_the_yaml_to_paste() -> None:
    r = report(revolute(-1, 215), np.linspace(-200, -10, 50))  # panda_joint6-like limits, logged negated
    assert r.verdict == "fits" and not r.current_fits
    assert r.paste == "s: {joint: j, unit: deg, sign: -1}"


def test_several_fitting_corrections_are_ambiguous() -> None:
    r = report(revolute(-166, 166), np.linspace(-30, 30, 50))
    assert r.verdict == "ambiguous" and "settle against a known pose" in r.message and r.current_fits
    assert r.fitting[0] == "identity (the config's)" and "negate" in r.fitting


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
    channel = JointChannel("finger", "f", 0, "m", 1.0, 1.0, 0.0, 0.0, 0.04, 0.0, HERE)
    r = report(channel, np.linspace(1, 39, 20))
    assert r.verdict == "fits" and r.paste == "f: {joint: finger, unit: mm}"


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

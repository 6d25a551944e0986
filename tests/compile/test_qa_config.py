"""`qa:` compiled into the plan's `QaPlan`: every threshold in SI units whatever unit the config wrote, the defaults
when it is omitted, and located refusals (tests/configs/invalid/qa_*.yaml run them through the CLI)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from urdf_pipeline.compile import FROM_CONFIG, check_config, compile_config
from urdf_pipeline.plan import QA_FLAGS, QaPlan

INVALID = Path(__file__).resolve().parents[1] / "configs" / "invalid"


def _config(examples_dir: Path, qa: str, name: str) -> Path:
    """The invalid cases' config, its data fixed, with `qa` (YAML text) appended."""
    text = (INVALID / "limit_violation.yaml").read_text(encoding="utf-8").replace("data/out_of_limits.parquet", "data/episode_000.parquet")
    path = examples_dir / f"qa_{name}.yaml"
    path.write_text(text + qa, encoding="utf-8")
    return path


def test_defaults_when_qa_is_omitted(examples_dir: Path) -> None:
    plan = compile_config(_config(examples_dir, "", "omitted"))
    assert plan.qa == QaPlan()
    assert plan.qa.fail_on == () and plan.qa.spike_jerk is None and plan.qa.gap_seconds is None


def test_every_threshold_in_si_units(examples_dir: Path) -> None:
    qa = (
        "qa:\n  static_velocity: {angle: 0.5 deg/s, length: 1 mm/s}\n  spike: {factor: 50, jerk: {angle: 2 rad/s^3, length: 30 cm/s^3}}\n"
        "  gap: 50 ms\n  length_outlier: 1.5\n  bias: {angle: 3 deg, length: 4 mm}\n  fail_on: [spike, nan, spike]\n"
    )
    plan = compile_config(_config(examples_dir, qa, "full")).qa
    assert plan.static_velocity.angle == pytest.approx(math.radians(0.5)) and plan.static_velocity.length == pytest.approx(1e-3)
    assert plan.spike_factor == 50
    assert plan.spike_jerk is not None and plan.spike_jerk.angle == 2 and plan.spike_jerk.length == pytest.approx(0.3)
    assert plan.gap_seconds == pytest.approx(0.05)
    assert plan.length_iqr == 1.5
    assert plan.bias.angle == pytest.approx(math.radians(3)) and plan.bias.length == pytest.approx(4e-3)
    assert plan.fail_on == ("spike", "nan")


def test_one_kind_keeps_the_other_default_and_steps_are_a_gap(examples_dir: Path) -> None:
    qa = "qa:\n  static_velocity: 2 mm/s\n  gap: 2.5 steps\n  bias: 0\n"
    plan = compile_config(_config(examples_dir, qa, "one_kind")).qa
    assert plan.static_velocity.length == pytest.approx(2e-3) and plan.static_velocity.angle == QaPlan().static_velocity.angle
    assert plan.gap_seconds is None and plan.gap_steps == 2.5
    assert plan.bias.angle == 0 and plan.bias.length == QaPlan().bias.length


@pytest.mark.parametrize(
    ("qa", "where", "message"),
    [
        ("  static_velocity: 5 deg\n", "qa.static_velocity", "unknown unit 'deg' in static_velocity '5 deg'; units are rad/s, deg/s; m/s"),
        ("  spike: {jerk: {length: 3 deg/s^3}}\n", "qa.spike.jerk.length", "is an angular jerk, but length takes a linear jerk"),
        ("  spike: {factor: -1}\n", "qa.spike.factor", "the spike factor -1 is negative"),
        ("  length_outlier: -2\n", "qa.length_outlier", "the IQR factor -2 is negative"),
        ("  gap: 3\n", "qa.gap", "gap 3 has no unit: write it with one, e.g. 3 ms or 3 steps"),
        ("  gap: soon\n", "qa.gap", "'soon' is not a gap: write NUMBER UNIT"),
        ("  static_velocity: {angle: -1 deg/s}\n", "qa.static_velocity.angle", "static_velocity '-1 deg/s' is negative"),
        ("  fail_on: [nann]\n", "qa.fail_on[0]", "unknown flag 'nann' (did you mean 'nan'?)"),
    ],
)
def test_refusals_are_located(examples_dir: Path, qa: str, where: str, message: str) -> None:
    compiled = check_config(_config(examples_dir, "qa:\n" + qa, "refused"), FROM_CONFIG)
    lines = [error.lines()[0] for error in compiled.errors]
    assert any(f"{where}: " in line and message in line for line in lines), lines


def test_the_vocabulary_is_the_issue_s() -> None:
    assert QA_FLAGS == ("spike", "static", "length_outlier", "timestamp_gap", "timestamp_order", "calibration_bias", "limits", "nan")

"""Unit conversion, sign, offset, limits with slack and mimic joints, on whole columns."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from urdf_pipeline.errors import Problems, UserError, Where
from urdf_pipeline.execute.limits_report import check_joint_statistics
from urdf_pipeline.plan import HeldJoint, IndexPlan, JointChannel, MimicJoint, ParquetSourcePlan, RobotPlan
from urdf_pipeline.sources.joint_values import JointValueMapper, raw_matrix

HERE = Where(Path("c.yaml"), 1)


def channel(
    joint: str,
    index: int,
    unit: str = "deg",
    sign: float = 1.0,
    offset: float = 0.0,
    lower: float | None = -1.0,
    upper: float | None = 1.0,
    slack_source: float = 2.0,
) -> JointChannel:
    factor = math.pi / 180 if unit == "deg" else (1e-3 if unit == "mm" else 1.0)
    return JointChannel(
        joint, f"s{index}", index, unit, factor, sign, offset, lower, upper, slack_source * factor, Where(Path("c.yaml"), 10 + index)
    )


def mapper(channels, holds=(), mimics=(), on_violation="error", width=3, nan_policy="error") -> JointValueMapper:
    source = ParquetSourcePlan(
        "src", Path("x.parquet"), "col", IndexPlan("frame_index", "sequence", None), tuple(f"s{i}" for i in range(width)), HERE
    )
    robot = RobotPlan(
        key="arm",
        urdf_path=Path("r.urdf"),
        urdf_text="",
        urdf_origin="file r.urdf",
        urdf_sha256="0" * 64,
        robot_name="r",
        root_link="base",
        links=("base",),
        joint_links=(),
        entity_path_prefix="/arm",
        frame_prefix="",
        keep_collisions=False,
        source="src",
        channels=tuple(channels),
        holds=tuple(holds),
        mimics=tuple(mimics),
        on_violation=on_violation,
        where=HERE,
        nan_policy=nan_policy,
    )
    return JointValueMapper(robot, source)


def test_conversion_order_is_unit_then_sign_then_offset() -> None:
    m = mapper([channel("a", 0, sign=-1, offset=0.1, lower=None, upper=None)], width=1)
    values, _ = m.urdf_values(np.array([[10.0]]))
    assert values[0, 0] == pytest.approx(-math.radians(10) + 0.1)


def test_within_slack_is_clamped_and_reported_once_per_joint() -> None:
    m = mapper([channel("a", 0, lower=0.0, upper=math.radians(90))], width=1)
    raw = np.array([[91.0], [91.5], [45.0], [-1.0]])
    values, _ = m.urdf_values(raw)
    assert values[:, 0].tolist() == pytest.approx([math.radians(90), math.radians(90), math.radians(45), 0.0])
    problems = Problems()
    notes = check_joint_statistics(m, problems)
    assert not problems.errors
    assert len(notes) == 1 and "clamped 3 of 4 rows" in notes[0] and "worst value 91.5 deg" in notes[0]


def test_beyond_slack_is_an_error_naming_joint_rows_worst_value_and_limit() -> None:
    m = mapper([channel("elbow", 1, lower=0.0, upper=math.radians(90))], width=2)
    m.urdf_values(np.array([[0.0, 95.0], [0.0, 120.0], [0.0, 10.0]]))
    problems = Problems()
    check_joint_statistics(m, problems)
    with pytest.raises(UserError) as error:
        problems.raise_if_any()
    message = error.value.message
    assert "'elbow'" in message and "2 of 3 rows" in message and "worst value 120 deg" in message and "[0, 90] deg" in message
    assert error.value.where.line == 11  # the map entry's line


@pytest.mark.parametrize("mode, expected", [("clamp", math.radians(90)), ("ignore", math.radians(120))])
def test_on_violation_clamp_and_ignore(mode: str, expected: float) -> None:
    m = mapper([channel("a", 0, lower=0.0, upper=math.radians(90))], on_violation=mode, width=1)
    assert m.urdf_values(np.array([[120.0]]))[0][0, 0] == pytest.approx(expected)
    problems = Problems()
    notes = check_joint_statistics(m, problems)
    assert not problems.errors and mode in notes[0]


def test_holds_and_mimic_joints_are_appended() -> None:
    m = mapper(
        [channel("driver", 0, unit="mm", lower=None, upper=None)],
        holds=[HeldJoint("held", 0.25)],
        mimics=[MimicJoint("follower", "driver", -2.0, 0.01)],
        width=1,
    )
    assert m.joint_names == ("driver", "held", "follower")
    values, _ = m.urdf_values(np.array([[10.0]]))
    assert values[0].tolist() == pytest.approx([0.01, 0.25, -0.01])


def test_value_count_must_match_names() -> None:
    m = mapper([channel("a", 0)], width=3)
    vectors = pa.array([[1.0, 2.0, 3.0], [1.0, 2.0]], pa.list_(pa.float64()))
    with pytest.raises(UserError, match="rows of 2 values but 3 names"):
        raw_matrix(m.source, vectors)


def test_nan_values_are_an_error_naming_the_joint() -> None:
    m = mapper([channel("a", 0, lower=None, upper=None)], width=1)
    m.urdf_values(np.array([[np.nan], [1.0]]))
    problems = Problems()
    check_joint_statistics(m, problems)
    assert "joint 'a'" in problems.errors[0].message and "1 of 2 rows are NaN" in problems.errors[0].message
    assert "the first at row 0" in problems.errors[0].message


def test_zero_rows_is_an_error() -> None:
    problems = Problems()
    check_joint_statistics(mapper([channel("a", 0)], width=1), problems)
    assert "yielded zero rows" in problems.errors[0].message


def test_first_nan_row_counts_across_batches() -> None:
    m = mapper([channel("a", 0, lower=None, upper=None)], width=1)
    m.urdf_values(np.zeros((5, 1)))
    m.urdf_values(np.array([[0.0], [0.0], [np.inf]]))
    problems = Problems()
    check_joint_statistics(m, problems)
    assert "the first at row 7 of the source" in problems.errors[0].message


def test_drop_row_leaves_rows_out_and_reports_the_count() -> None:
    m = mapper([channel("a", 0, lower=None, upper=None), channel("b", 1, lower=None, upper=None)], width=2, nan_policy="drop_row")
    values, left_out = m.urdf_values(np.array([[1.0, 2.0], [np.nan, 2.0], [1.0, 2.0]]))
    assert left_out.tolist() == [False, True, False]
    problems = Problems()
    notes = check_joint_statistics(m, problems)
    assert not problems.errors and "left out 1 of 3 rows" in notes[0]


def test_hold_last_fills_from_the_previous_batch_and_drops_leading_nans() -> None:
    m = mapper([channel("a", 0, unit="rad", lower=None, upper=None)], width=1, nan_policy="hold_last")
    values, left_out = m.urdf_values(np.array([[np.nan], [1.0], [np.nan]]))
    assert left_out.tolist() == [True, False, False] and values[2, 0] == 1.0
    values, left_out = m.urdf_values(np.array([[np.nan], [3.0]]))
    assert left_out is None and values[:, 0].tolist() == [1.0, 3.0]
    notes = check_joint_statistics(m, Problems())
    assert any("filled 2 of 5 rows" in n for n in notes) and any("left out 1 of 5" in n for n in notes)


def test_wrap_lands_values_in_the_period_around_the_middle_of_the_range() -> None:
    c = replace(channel("servo", 0, lower=-math.pi, upper=math.pi), wrap=360.0, wrap_center=0.0)
    m = mapper([c], width=1)
    values, _ = m.urdf_values(np.array([[350.0], [10.0], [190.0], [-200.0]]))
    assert values[:, 0].tolist() == pytest.approx(np.radians([-10.0, 10.0, -170.0, 160.0]).tolist())


def test_source_range_maps_percent_onto_the_joint_limits() -> None:
    c = replace(channel("gripper", 0, lower=0.0, upper=0.04), source_range=(0.0, 100.0), target_range=(0.0, 0.04))
    m = mapper([c], width=1)
    values, _ = m.urdf_values(np.array([[0.0], [50.0], [100.0]]))
    assert values[:, 0].tolist() == pytest.approx([0.0, 0.02, 0.04])
    assert c.to_source_unit(0.04) == pytest.approx(100.0)


def test_scale_applies_after_unit_and_before_sign_and_offset() -> None:
    c = replace(channel("a", 0, unit="deg", sign=-1.0, offset=0.5, lower=None, upper=None), scale=0.5)
    values, _ = mapper([c], width=1).urdf_values(np.array([[90.0]]))
    assert values[0, 0] == pytest.approx(-math.radians(45.0) + 0.5)

"""Trails (`trails:`): the positions written to each trail's entity equal pinocchio's link poses composed with the
calibration edge, at every row; a line's rows are the segments between consecutive positions; the blueprint holds
each trail's window; the recording's FK is what it was without trails."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import RrdReader

from urdf_pipeline.examples import write_joint_parquet

from ..reference_fk import PinocchioRobot
from ..rrd_frames import pose, read_frames
from .test_fk_against_pinocchio import PANDA_ARM, panda_contract_raw, panda_joint_values, random_within_limits, variant

TOLERANCE_M = 1e-5  # the positions are float32, as Rerun's: ~1e-7 m at a metre
ROWS = 64
EDGE_Q = [0.1, -0.3, 0.4, 0.8]  # the calibration edge world -> panda_link0, rotated so a wrong composition shows
TRAILS = [
    {"link": "panda_hand", "window": "50 rows", "color": [255, 80, 0]},  # in world (the default), a line
    {"link": "panda_link4", "frame": "panda_link0", "style": "points", "window": "20 rows"},  # the robot's root
    {"link": "panda_leftfinger", "frame": "panda_link5", "style": "points"},  # a link above it, past fixed joints
]


def _trail_rows(path: Path, entity: str, component: str) -> dict[int, object]:
    """frame_index -> the row's component value (None where the row is left out), from the written recording."""
    rows: dict[int, object] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if str(chunk.entity_path) != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if component in batch.schema.names:
            rows.update(zip(batch.column("frame_index").to_pylist(), batch.column(component).to_pylist(), strict=True))
    return rows


def _component_type(path: Path, entity: str, component: str) -> pa.DataType:
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        if str(chunk.entity_path) == entity and component in batch.schema.names:
            return batch.schema.field(component).type
    raise AssertionError(f"no {component} on {entity}")


def _statics(path: Path, entity: str) -> dict[str, object]:
    found: dict[str, object] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if str(chunk.entity_path) == entity and chunk.is_static:
            found.update({k: v for k, v in chunk.to_record_batch().to_pylist()[0].items() if k != "rerun.controls.RowId"})
    return found


def _with_trails(examples_dir: Path, name: str, trails: list[dict]) -> Path:
    def edit(data: dict) -> None:
        data["sources"]["arm_state"]["parquet"] = "data/random_trails.parquet"
        data["edges"][0]["quaternion_xyzw"] = EDGE_Q
        data["trails"] = trails

    return variant(examples_dir, "demo.yaml", name, edit)


def test_trails_match_pinocchio(examples_dir: Path, run_cli) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=ROWS, seed=26)
    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", panda_contract_raw(q))
    result = run_cli("run", str(_with_trails(examples_dir, "trails_panda", TRAILS)))
    assert result.code == 0, result.err
    recording = Path(result.out.strip())

    world_from_base = pose([0.0, 0.0, 0.5], EDGE_Q)
    links = [reference.link_poses(panda_joint_values(row)) for row in q]
    hand = np.array([(world_from_base @ poses["panda_hand"])[:3, 3] for poses in links])
    link4 = np.array([poses["panda_link4"][:3, 3] for poses in links])
    finger = np.array([(np.linalg.inv(poses["panda_link5"]) @ poses["panda_leftfinger"])[:3, 3] for poses in links])

    strips = _trail_rows(recording, "/arm/trails/panda_hand", "LineStrips3D:strips")
    assert sorted(strips) == list(range(ROWS))
    segments = np.array([strips[row] for row in range(ROWS)])  # rows x 1 strip x 2 points x 3
    previous = np.vstack([hand[:1], hand[:-1]])  # the first row: a segment of zero length at the first position
    np.testing.assert_allclose(segments[:, 0, 1], hand, atol=TOLERANCE_M)
    np.testing.assert_allclose(segments[:, 0, 0], previous, atol=TOLERANCE_M)
    for entity, expected in (("/arm/trails/panda_link4", link4), ("/arm/trails/panda_leftfinger", finger)):
        points = _trail_rows(recording, entity, "Points3D:positions")
        np.testing.assert_allclose(np.array([points[row] for row in range(ROWS)])[:, 0], expected, atol=TOLERANCE_M, err_msg=entity)

    # The viewer refuses a component whose arrow type differs from the SDK's (a nullable float item, pyarrow's default).
    position_type = rr.components.Position3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type
    strip_type = rr.components.LineStrip3DBatch([[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]]).as_arrow_array().type
    assert _component_type(recording, "/arm/trails/panda_hand", "LineStrips3D:strips") == pa.list_(strip_type)
    assert _component_type(recording, "/arm/trails/panda_link4", "Points3D:positions") == pa.list_(position_type)
    assert _statics(recording, "/arm/trails/panda_hand")["CoordinateFrame:frame"] == ["world"]
    assert _statics(recording, "/arm/trails/panda_link4")["CoordinateFrame:frame"] == ["panda_link0"]
    assert _statics(recording, "/arm/trails/panda_hand")["LineStrips3D:colors"] == [0xFF5000FF]

    # The FK is the same as without trails: the composed world pose of the hand is the trail's last point.
    frames = read_frames(recording, "frame_index")
    np.testing.assert_allclose(frames.world_pose("panda_hand", 17, "world")[:3, 3], hand[17], atol=TOLERANCE_M)


def test_blueprint_holds_the_window(examples_dir: Path, run_cli) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=ROWS, seed=27)
    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", panda_contract_raw(q))
    result = run_cli("run", str(_with_trails(examples_dir, "trails_window", TRAILS[:2])))
    assert result.code == 0, result.err
    blueprint = Path(result.out.strip()).with_name("trails_window.rbl")
    reader = RrdReader(blueprint)
    ranges = [
        row["VisibleTimeRanges:ranges"]
        for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks()
        if "VisibleTimeRanges:ranges" in (batch := chunk.to_record_batch()).schema.names
        for row in batch.to_pylist()
    ]
    assert len(ranges) == 2  # the scene's 3D view and the robot's
    for views in ranges:
        assert [r["timeline"] for r in views] == ["frame_index"]
        assert views[0]["range"]["start"] == -50  # the widest window, relative to the time cursor
        assert views[0]["range"]["end"] == 0


def test_rows_left_out_and_a_time_index(examples_dir: Path, run_cli) -> None:
    """`joints.nan: drop_row`: a row without a pose has no trail row, and the line goes on from the last position
    kept. On a timestamp index the window is a duration, and the blueprint's range is in seconds."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=ROWS, seed=28)
    raw = panda_contract_raw(q)
    raw[[5, 6, 40], 2] = np.nan
    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", raw)

    def edit(data: dict) -> None:
        data["sources"]["arm_state"].update(parquet="data/random_trails.parquet", index={"timestamp": "timestamp", "unit": "s"})
        data["robots"]["arm"]["joints"]["nan"] = "drop_row"
        data["edges"][0]["quaternion_xyzw"] = EDGE_Q
        data["trails"] = [{"link": "panda_hand", "window": "1.5 s"}]

    result = run_cli("run", str(variant(examples_dir, "demo.yaml", "trails_dropped", edit)))
    assert result.code == 0, result.err
    recording = Path(result.out.strip())
    world_from_base = pose([0.0, 0.0, 0.5], EDGE_Q)
    hand = np.array([(world_from_base @ reference.link_poses(panda_joint_values(row))["panda_hand"])[:3, 3] for row in q])
    rows: dict[int, object] = {}
    for chunk in RrdReader(recording).stream().to_chunks():
        batch = chunk.to_record_batch()
        if str(chunk.entity_path) == "/arm/trails/panda_hand" and not chunk.is_static:
            times = batch.column("timestamp").cast("int64").to_pylist()
            rows.update(zip(times, batch.column("LineStrips3D:strips").to_pylist(), strict=True))
    by_row = [rows.get(round(index / 30.0 * 1e9), "absent") for index in range(ROWS)]
    kept = [index for index in range(ROWS) if index not in (5, 6, 40)]
    assert all(by_row[index] in (None, "absent") for index in (5, 6, 40))
    for before, index in zip([kept[0], *kept[:-1]], kept, strict=True):
        np.testing.assert_allclose(np.array(by_row[index])[0], [hand[before], hand[index]], atol=TOLERANCE_M, err_msg=f"row {index}")
    blueprint = recording.with_name("trails_dropped.rbl")
    reader = RrdReader(blueprint)
    ranges = [
        row["VisibleTimeRanges:ranges"]
        for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks()
        if "VisibleTimeRanges:ranges" in (batch := chunk.to_record_batch()).schema.names
        for row in batch.to_pylist()
    ]
    assert ranges and all(views[0]["timeline"] == "timestamp" and views[0]["range"]["start"] == -1_500_000_000 for views in ranges)


def test_validate_without_data_refuses_a_bad_trail(examples_dir: Path, run_cli) -> None:
    config = variant(examples_dir, "demo.yaml", "trails_no_data", lambda d: d.update(trails=[{"link": "panda_hnad"}]))
    result = run_cli("validate", "--no-data", str(config))
    assert result.code == 1
    assert "trails[0].link: robot 'arm' has no link 'panda_hnad' (did you mean 'panda_hand'?)" in result.err


def test_bottom_up_positions_equal_the_composed_joint_transforms(examples_dir: Path) -> None:
    """The fast path (positions moved up joint by joint) is taken, and equals the FK's transforms composed top down,
    for a chain of turns, fixed joints and a slide (the finger), under a rotated calibration edge."""
    from urdf_pipeline.compile import compile_config
    from urdf_pipeline.execute.model_stream import cached_tree
    from urdf_pipeline.execute.trail_stream import TrailPositions
    from urdf_pipeline.sources import JointValueMapper

    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", np.zeros((4, 8)))
    plan = compile_config(_with_trails(examples_dir, "trails_unit", TRAILS))
    robot = plan.robots[0]
    names = list(JointValueMapper(robot, plan.for_segment(plan.segments[0]).sources[0]).joint_names)
    values = np.random.default_rng(29).uniform(-3.0, 3.0, (500, len(names)))
    for trail in plan.trails:
        positions = TrailPositions(trail, cached_tree(robot), names)
        assert positions.fast, trail.link
        np.testing.assert_allclose(positions.positions(values), positions.composed(values), atol=1e-12, err_msg=trail.link)


def test_a_line_is_continuous_across_blocks(examples_dir: Path, run_cli) -> None:
    """5000 rows come in several blocks (the parquet reader's 1024-row chunks, joined into 2048-row blocks): each
    row's segment starts where the previous row's ended, and matches pinocchio at the blocks' edges."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    rows = 5000
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=rows, seed=30)
    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", panda_contract_raw(q))
    result = run_cli("run", str(_with_trails(examples_dir, "trails_blocks", [{"link": "panda_hand"}])))
    assert result.code == 0, result.err
    strips = _trail_rows(Path(result.out.strip()), "/arm/trails/panda_hand", "LineStrips3D:strips")
    segments = np.array([strips[row] for row in range(rows)])[:, 0]  # rows x 2 points x 3
    np.testing.assert_array_equal(segments[1:, 0], segments[:-1, 1])
    world_from_base = pose([0.0, 0.0, 0.5], EDGE_Q)
    for row in (0, 1023, 1024, 2047, 2048, 4095, 4096, rows - 1):
        expected = (world_from_base @ reference.link_poses(panda_joint_values(q[row]))["panda_hand"])[:3, 3]
        np.testing.assert_allclose(segments[row, 1], expected, atol=TOLERANCE_M, err_msg=f"row {row}")


def _window_start(blueprint: Path) -> int:
    reader = RrdReader(blueprint)
    for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
        batch = chunk.to_record_batch()
        if "VisibleTimeRanges:ranges" in batch.schema.names:
            return int(batch.to_pylist()[0]["VisibleTimeRanges:ranges"][0]["range"]["start"])
    raise AssertionError("no visible time range")


def test_a_new_window_rewrites_the_blueprint_only(examples_dir: Path, run_cli) -> None:
    """The window is the blueprint's: changing it leaves the recordings up to date; a new trail makes them stale."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=10, seed=31)
    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", panda_contract_raw(q))
    config = _with_trails(examples_dir, "trails_stale", [{"link": "panda_hand", "window": "5 rows"}])
    assert run_cli("run", str(config)).code == 0
    blueprint = config.with_name("out") / "trails_stale.rbl"
    assert _window_start(blueprint) == -5
    config.write_text(config.read_text().replace("window: 5 rows", "window: 7 rows"))
    again = run_cli("run", str(config))
    assert again.code == 0 and "is up to date" in again.err
    assert _window_start(blueprint) == -7
    config.write_text(config.read_text().replace("link: panda_hand", "link: panda_link7"))
    third = run_cli("run", str(config))
    assert third.code == 0 and "is up to date" not in third.err


def test_plan_and_diff_show_the_trails(examples_dir: Path, run_cli) -> None:
    """A reviewer sees what a pull request's trails draw: plan in every format, and diff when one changes."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    q = random_within_limits(reference, [*PANDA_ARM, "panda_finger_joint1"], frames=10, seed=31)
    write_joint_parquet(examples_dir / "data" / "random_trails.parquet", panda_contract_raw(q))
    config = _with_trails(examples_dir, "trails_review", [{"link": "panda_hand", "window": "5 rows", "style": "points"}])
    text = run_cli("plan", str(config))
    assert text.code == 0, text.err
    assert "trail of arm's panda_hand in world: points, window 5 rows (trails)" in text.out
    markdown = run_cli("plan", str(config), "--format", "markdown")
    assert "trail of `arm`'s `panda_hand` in `world`: points, window 5 rows (`trails`)" in markdown.out
    data = json.loads(run_cli("plan", str(config), "--format", "json").out)
    assert data["output"]["trails"] == [{"robot": "arm", "link": "panda_hand", "frame": "world", "style": "points", "window": "5 rows"}]
    assert "trails" not in json.loads(run_cli("plan", str(examples_dir / "demo.yaml"), "--format", "json").out)["output"]
    changed = config.with_name("trails_review_new.yaml")
    changed.write_text(config.read_text().replace("link: panda_hand", "link: panda_link7"))
    diff = run_cli("diff", str(config), str(changed))
    assert "trails trail of arm's panda_hand in world" in diff.out and "-> trail of arm's panda_link7 in world" in diff.out, diff.out

"""`output.joint_series`: the driven joints' values as Rerun time series, beside the FK, with a blueprint that plots
them. Each expected value is converted here, by hand with numpy, from the source file the test wrote; the poses are
checked against pinocchio."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml
from rerun.chunk import RrdReader

from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames
from .test_fk_against_pinocchio import PANDA_ARM, assert_poses_match, random_within_limits

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs in tmp_path read the session's examples

SERIES = "/arm/joint_values"
FK = "/arm/joint_transforms"
NAMES = ["j1", "j2", "j3", "j4", "j5", "j6", "j7", "grip"]
MAPPED = [*PANDA_ARM, "panda_finger_joint1"]  # panda_finger_joint2 is its <mimic>: not plotted


def _timelines(batch: pa.RecordBatch) -> dict[str, np.ndarray]:
    return {
        field.name: np.asarray(column.cast(pa.int64()))
        for field, column in zip(batch.schema, batch.columns, strict=True)
        if (field.metadata or {}).get(b"rerun:kind") == b"index"
    }


def read_entity(path: Path, entity: str, component: str) -> tuple[dict[str, np.ndarray], list[Any], list[Any]]:
    """(timeline -> values, the component's rows, its static rows) of one entity, rows sorted by their first timeline."""
    times: dict[str, list[np.ndarray]] = {}
    rows: list[Any] = []
    static: list[Any] = []
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        if chunk.is_static:
            static += batch.to_pylist()
            continue
        for name, values in _timelines(batch).items():
            times.setdefault(name, []).append(values)
        rows += batch.column(component).to_pylist()
    joined = {name: np.concatenate(parts) for name, parts in times.items()}
    if joined:
        order = np.argsort(next(iter(joined.values())), kind="stable")
        joined = {name: values[order] for name, values in joined.items()}
        rows = [rows[i] for i in order]
    return joined, rows, static


def read_series(path: Path, entity: str = SERIES) -> tuple[dict[str, np.ndarray], np.ndarray, list[str]]:
    """(timelines, rows x joints values with NaN for a row left out, the series' names)."""
    times, rows, static = read_entity(path, entity, "Scalars:scalars")
    width = max((len(r) for r in rows if r is not None), default=0)
    values = np.array([r if r is not None else [np.nan] * width for r in rows], dtype=np.float64).reshape(len(rows), width)
    names = [name for row in static for name in (row.get("SeriesLines:names") or [])]
    return times, values, names


def blueprint_views(path: Path) -> list[tuple[str, str, str]]:
    """(kind, name, origin) of each view of a .rbl."""
    reader = RrdReader(path)
    (store,) = reader.blueprints()
    views = []
    for chunk in reader.stream(store=store).to_chunks():
        row = chunk.to_record_batch().to_pylist()[0]
        if "ViewBlueprint:class_identifier" in row:
            views.append(
                (row["ViewBlueprint:class_identifier"][0], row["ViewBlueprint:display_name"][0], row["ViewBlueprint:space_origin"][0])
            )
    return sorted(views)


def panda_config(examples_dir: Path, tmp_path: Path, source: dict[str, Any], joints: dict[str, Any], series: bool = True) -> Path:
    output: dict[str, Any] = {"path": "out/{segment}.rrd", "application_id": "series", "segment": "take"}
    if series:
        output["joint_series"] = True
    config = {
        "version": 1,
        "sources": {"s": source},
        "robots": {
            "arm": {
                "urdf": str(examples_dir / "robots" / "panda.urdf"),
                "package_paths": {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")},
                "joints": {"source": "s", **joints},
            }
        },
        "output": output,
    }
    path = tmp_path / "series.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return path


CORRECTED = {
    "unit": "deg",
    "limits": {"slack": {"angle": "2 deg", "length": "2 mm"}},
    "map": {
        "j1": {"joint": "panda_joint1", "wrap": 360},
        "j2": {"joint": "panda_joint2", "sign": -1},
        "j3": {"joint": "panda_joint3", "offset": 0.1},
        "j4": {"joint": "panda_joint4", "scale": 2.0},
        "j5": "panda_joint5",
        "j6": "panda_joint6",
        "j7": "panda_joint7",
        "grip": {"joint": "panda_finger_joint1", "unit": "mm"},
    },
}


def corrected_by_hand(raw: np.ndarray, reference: PinocchioRobot) -> np.ndarray:
    """CORRECTED's conversion written out: wrap into [-180, 180) deg, degrees to radians, sign, offset (rad), scale,
    mm to m, then values past a limit (within the slack) clamped onto it."""
    expected = np.radians(raw[:, :7])
    expected[:, 0] = np.radians(np.mod(raw[:, 0] + 180.0, 360.0) - 180.0)
    expected[:, 1] = -np.radians(raw[:, 1])
    expected[:, 2] = np.radians(raw[:, 2]) + 0.1
    expected[:, 3] = np.radians(raw[:, 3] * 2.0)
    expected = np.concatenate([expected, raw[:, 7:8] / 1000.0], axis=1)
    bounds = np.array([reference.limits(joint) for joint in MAPPED])
    return np.clip(expected, bounds[:, 0], bounds[:, 1])


def test_series_are_the_corrected_values_on_the_fk_timelines(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    frames = 40
    q = random_within_limits(reference, MAPPED, frames=frames, seed=23)
    raw = np.empty((frames, 8))
    raw[:, 0] = np.mod(np.degrees(q[:, 0]), 360.0)  # a servo reporting 0..360
    raw[:, 1] = -np.degrees(q[:, 1])
    raw[:, 2] = np.degrees(q[:, 2] - 0.1)
    raw[:, 3] = np.degrees(q[:, 3]) / 2.0
    raw[:, 4:7] = np.degrees(q[:, 4:7])
    raw[:, 7] = q[:, 7] * 1000.0
    raw[5, 4] = np.degrees(reference.limits("panda_joint5")[1]) + 1.5  # past the limit, within the 2 deg slack: clamped
    index = 1000 + 3 * np.arange(frames)  # not 0..N-1: the timeline's own values are checked
    parquet = tmp_path / "state.parquet"
    state = pa.FixedSizeListArray.from_arrays(pa.array(raw.astype(np.float32).reshape(-1)), 8)
    pq.write_table(pa.table({"frame_index": pa.array(index, pa.int64()), "observation.state": state}), parquet)
    source = {"parquet": "state.parquet", "column": "observation.state", "index": "frame_index", "names": NAMES}
    config = panda_config(examples_dir, tmp_path, source, CORRECTED)

    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    recording = Path(result.out.strip())
    # The source as stored (float32), read back and converted here: what the FK must have used.
    stored = np.asarray(pq.read_table(parquet).column("observation.state").combine_chunks().flatten(), dtype=np.float64)
    expected = corrected_by_hand(stored.reshape(frames, 8), reference)
    times, values, names = read_series(recording)
    assert names == MAPPED
    assert values.shape == (frames, 8)
    np.testing.assert_allclose(values, expected, rtol=0, atol=1e-12)
    assert values[5, 4] == reference.limits("panda_joint5")[1]
    fk_times, _, _ = read_entity(recording, FK, "Transform3D:child_frame")
    assert set(times) == set(fk_times) == {"frame_index"}
    assert list(times["frame_index"]) == list(index) == sorted(set(fk_times["frame_index"]))
    recorded = read_frames(recording, "frame_index")
    for row in (0, 5, 17, frames - 1):  # the FK drew the pose of exactly these values
        joint_values = dict(zip(MAPPED, expected[row], strict=True)) | {"panda_finger_joint2": expected[row, 7]}
        for link, pose in reference.link_poses(joint_values).items():
            assert_poses_match(recorded.world_pose(link, int(index[row]), "panda_link0"), pose, f"{link} at row {row}")
    views = blueprint_views(recording.parent / "series.rbl")
    assert ("TimeSeries", "arm joints", SERIES) in views
    assert ("3D", "scene", "/") in views and ("3D", "arm", "/arm") in views


def test_rows_left_out_are_gaps_and_timestamps_are_the_fks(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    """A CSV with a timestamp index: a row the NaN policy drops is a null in the series as in the FK."""
    reference = PinocchioRobot(examples_dir / "robots" / "panda.urdf")
    frames = 30
    q = random_within_limits(reference, MAPPED, frames=frames, seed=24)
    raw = np.concatenate([np.degrees(q[:, :7]), q[:, 7:] * 1000.0], axis=1)
    raw[7, 2] = np.nan
    seconds = 1_700_000_000.0 + np.arange(frames) / 64.0  # exact in binary
    lines = ["t," + ",".join(NAMES), *(",".join(f"{float(v):.17g}" for v in (t, *row)) for t, row in zip(seconds, raw, strict=True))]
    (tmp_path / "state.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    source = {"csv": "state.csv", "index": {"timestamp": "t", "unit": "s"}}
    joints = {
        "unit": "deg",
        "nan": "drop_row",
        "map": {**{f"j{i}": f"panda_joint{i}" for i in range(1, 8)}, "grip": {"joint": "panda_finger_joint1", "unit": "mm"}},
    }
    config = panda_config(examples_dir, tmp_path, source, joints)

    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    recording = Path(result.out.strip())
    times, values, names = read_series(recording)
    assert names == MAPPED
    expected = np.concatenate([np.radians(raw[:, :7]), raw[:, 7:] / 1000.0], axis=1)
    expected[7] = np.nan  # left out: no value plotted, as no pose is drawn
    np.testing.assert_allclose(values, expected, rtol=0, atol=1e-12)
    fk_times, fk_rows, _ = read_entity(recording, FK, "Transform3D:child_frame")
    assert set(times) == set(fk_times) == {"t"}
    assert list(times["t"]) == sorted(set(fk_times["t"])) == [round(s * 1e9) for s in seconds]
    assert {row is None for row, t in zip(fk_rows, fk_times["t"], strict=True) if t == times["t"][7]} == {True}


def test_without_the_option_the_recording_holds_no_series(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    demo = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    source = demo["sources"]["arm_state"] | {"parquet": str(examples_dir / "data" / "episode_000.parquet")}
    joints = {key: value for key, value in demo["robots"]["arm"]["joints"].items() if key != "source"}
    config = panda_config(examples_dir, tmp_path, source, joints, series=False)
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    recording = Path(result.out.strip())
    entities = {chunk.entity_path for chunk in RrdReader(recording).stream().to_chunks()}
    assert FK in entities and SERIES not in entities
    assert not any(
        chunk.to_record_batch().schema.get_field_index("Scalars:scalars") >= 0 for chunk in RrdReader(recording).stream().to_chunks()
    )
    assert [view for view in blueprint_views(recording.parent / "series.rbl") if view[0] != "3D"] == []
    stamp = recording.stat().st_mtime_ns

    # Setting the option makes the segment out of date (its content hash changes): written again, then up to date.
    config.write_text(config.read_text().replace("  segment: take\n", "  segment: take\n  joint_series: true\n"))
    again = run_cli("run", str(config))
    assert again.code == 0, again.err
    assert recording.stat().st_mtime_ns != stamp
    assert SERIES in {chunk.entity_path for chunk in RrdReader(recording).stream().to_chunks()}
    assert ("TimeSeries", "arm joints", SERIES) in blueprint_views(recording.parent / "series.rbl")
    stamp = recording.stat().st_mtime_ns
    assert run_cli("run", str(config)).code == 0
    assert recording.stat().st_mtime_ns == stamp


def test_split_layout_puts_the_series_in_each_layer_and_none_in_the_model(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    data = yaml.safe_load((examples_dir / "so101_dataset.yaml").read_text())
    data["sources"]["so101"]["lerobot"] = str(examples_dir / "data" / "so101_lerobot")
    robot = data["robots"]["so101"]
    robot["urdf"] = str(examples_dir / robot["urdf"])
    robot["package_paths"] = {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")}
    data["output"].update(joint_series=True, episodes="0:2", model="out/model.rrd", path="out/{segment}.rrd")
    config = tmp_path / "split.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    out = tmp_path / "out"
    assert {chunk.entity_path for chunk in RrdReader(out / "model.rrd").stream().to_chunks()}.isdisjoint({"/so101/joint_values"})
    reference = PinocchioRobot(Path(robot["urdf"]))
    joints = list(robot["joints"]["map"].values())
    bounds = np.array([reference.limits(joint) for joint in joints])
    for episode in (0, 1):
        table = pq.read_table(examples_dir / "data" / "so101_lerobot" / "data" / "chunk-000" / f"episode_{episode:06d}.parquet")
        state = table.column("observation.state").combine_chunks()
        raw = np.asarray(state.flatten(), dtype=np.float64).reshape(len(table), -1)
        times, values, names = read_series(out / f"episode_{episode:06d}.rrd", "/so101/joint_values")
        assert names == joints
        np.testing.assert_allclose(values, np.clip(np.radians(raw), bounds[:, 0], bounds[:, 1]), rtol=0, atol=1e-12)
        assert list(times["frame_index"]) == table.column("frame_index").to_pylist()
        fk_times, _, _ = read_entity(out / f"episode_{episode:06d}.rrd", "/so101/joint_transforms", "Transform3D:child_frame")
        assert set(times) == set(fk_times)
        assert all(list(times[name]) == sorted(set(fk_times[name])) for name in times)
    assert ("TimeSeries", "so101 joints", "/so101/joint_values") in blueprint_views(out / "split.rbl")

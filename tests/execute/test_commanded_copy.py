"""`compare:` and `appearance:`: a commanded SO-101 (LeRobot `action`) beside the measured one (`observation.state`),
both against pinocchio, its meshes in the configured colour, and the per-episode differences against numpy's."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml
from rerun.chunk import RrdReader

from urdf_pipeline.compile import compile_config
from urdf_pipeline.dataset.fingerprint import model_hash, segment_hashes
from urdf_pipeline.examples import write_lerobot_dataset
from urdf_pipeline.execute.differences import PairDifferences
from urdf_pipeline.execute.manifest_entry import JointDifferences
from urdf_pipeline.plan import Comparison, JointChannel, QaPlan, RobotPlan

from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames
from .test_fk_against_pinocchio import SO101_JOINTS, check_robot, random_within_limits

FRAMES = 50
COLOR = [1.0, 0.5, 0.0]
OPACITY = 0.4


def write_commanded_dataset(root: Path, measured: list[np.ndarray], commanded: list[np.ndarray]) -> None:
    """A LeRobot v2.1 dataset whose rows hold `observation.state` (measured) and `action` (commanded), degrees."""
    write_lerobot_dataset(root, measured, SO101_JOINTS)
    for episode, values in enumerate(commanded):
        path = root / "data" / "chunk-000" / f"episode_{episode:06d}.parquet"
        table = pq.read_table(path)
        action = pa.FixedSizeListArray.from_arrays(pa.array(values.astype(np.float32).reshape(-1)), values.shape[1])
        pq.write_table(table.append_column("action", action), path)
    info_path = root / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"]["action"] = dict(info["features"]["observation.state"])
    info_path.write_text(json.dumps(info, indent=2))


def commanded_config(examples_dir: Path, name: str, dataset: str, robot_extra: dict | None = None) -> Path:
    """Two SO-101s from one dataset: `arm` (observation.state) and `cmd` (action), a copy with its own prefixes."""
    data = yaml.safe_load((examples_dir / "so101_dataset.yaml").read_text())
    arm = data["robots"]["so101"]
    data["sources"] = {
        "state": {"lerobot": dataset, "feature": "observation.state"},
        "action": {"lerobot": dataset, "feature": "action"},
    }
    arm["joints"]["source"] = "state"
    cmd = json.loads(json.dumps(arm))
    cmd["joints"]["source"] = "action"
    cmd.update(
        {
            "frame_prefix": "cmd_",
            "appearance": {"color": COLOR, "opacity": OPACITY},
            "compare": {"robot": "arm", "threshold": {"angle": "2 deg", "length": "5 mm"}},
            **(robot_extra or {}),
        }
    )
    data["robots"] = {"arm": arm, "cmd": cmd}
    data["frames"] = {"root": "world"}
    data["edges"] = [
        {"parent": "world", "child": "base_link", "translation": [0, 0, 0], "rpy": [0, 0, 0]},
        {"parent": "world", "child": "cmd_base_link", "translation": [0, 0, 0], "rpy": [0, 0, 0]},
    ]
    data["output"].update(model=f"out/{name}/model.rrd", path=f"out/{name}/{{segment}}.rrd", application_id=name, episodes="all")
    path = examples_dir / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def episodes(reference: PinocchioRobot) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Two episodes of measured q (rad) and commanded q: episode 0 off by 3 deg on elbow_flex in rows 10..19, episode
    1 off by 1 deg everywhere (within the 2 deg threshold) but by 3.5 deg on the gripper at row 5 (within 90% of the limits)."""
    measured = [0.9 * random_within_limits(reference, SO101_JOINTS, frames=FRAMES, seed=seed) for seed in (21, 22)]
    commanded = [q.copy() for q in measured]
    commanded[0][10:20, 2] += np.radians(3.0)
    commanded[1] += np.radians(1.0)
    commanded[1][5, 5] += np.radians(2.5)
    return measured, commanded


def _colours(path: Path) -> dict[str, list[int]]:
    """entity -> the static colour components it holds (albedo_factor or colors), packed RGBA, last one logged."""
    found: dict[str, list[int]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith(":albedo_factor") or name.endswith(":colors"):
                found[chunk.entity_path] = batch.column(name).flatten().to_pylist()
    return found


def test_commanded_copy_is_drawn_apart_and_its_differences_are_listed(examples_dir: Path, run_cli, erd_share: Path) -> None:
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    measured, commanded = episodes(reference)
    write_commanded_dataset(examples_dir / "data" / "cmd_so101", [np.degrees(q) for q in measured], [np.degrees(q) for q in commanded])
    config = commanded_config(examples_dir, "cmd_so101", "data/cmd_so101")
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    # run lists each episode's joints beyond the threshold, or says the copy kept within it
    lines = [line for line in result.err.splitlines() if "'cmd' against 'arm'" in line]
    assert len(lines) == 2, result.err
    assert "episode_000000: 'cmd' against 'arm' over 50 rows: 10 rows beyond {angle: 2 deg, length: 5 mm}: elbow_flex" in lines[0]
    assert "elbow_flex (max 3 deg, 10 rows)" in lines[0]
    assert "1 rows beyond" in lines[1] and "gripper (max 3.5 deg, 1 rows)" in lines[1] and "elbow_flex" not in lines[1]

    out = examples_dir / "out" / "cmd_so101"
    # both copies' poses equal pinocchio's
    for episode, (q_arm, q_cmd) in enumerate(zip(measured, commanded, strict=True)):
        frames = read_frames([out / "model.rrd", out / f"episode_{episode:06d}.rrd"], "frame_index")
        for prefix, q in (("", q_arm), ("cmd_", q_cmd)):
            values = [dict(zip(SO101_JOINTS, row, strict=True)) for row in q]
            assert check_robot(frames, list(range(FRAMES)), reference, values, prefix, np.eye(4), "world", [0, 12, 49]) > 0

    # the copy's meshes carry the configured colour and alpha; the measured robot's keep the URDF's
    packed = int.from_bytes(bytes([round(c * 255) for c in [*COLOR, OPACITY]]), "big")
    colours = _colours(out / "model.rrd")
    cmd_visuals = {e: c for e, c in colours.items() if e.startswith("/cmd/")}
    assert cmd_visuals and all(c == [packed] for c in cmd_visuals.values()), cmd_visuals
    assert not any(c == [packed] for e, c in colours.items() if e.startswith("/arm/"))

    # the manifest's summaries hold the differences, equal to numpy's on the written (float32, degrees) values
    manifest = json.loads((out / "cmd_so101.manifest.json").read_text())
    summaries = {entry["segment"]: entry["summary"] for entry in manifest["segments"]}
    for episode, (q_arm, q_cmd) in enumerate(zip(measured, commanded, strict=True)):
        written = [np.radians(np.degrees(q).astype(np.float32).astype(np.float64)) for q in (q_arm, q_cmd)]
        difference = np.abs(written[1] - written[0])
        stored = summaries[f"episode_{episode:06d}"]["differences"][0]
        assert stored["joints"] == SO101_JOINTS
        np.testing.assert_allclose(stored["largest"], difference.max(axis=0), rtol=1e-9, atol=1e-12)
        assert stored["beyond"] == (difference > np.radians(2.0)).sum(axis=0).tolist()
        assert stored["rows_beyond"] == int((difference > np.radians(2.0)).any(axis=1).sum())
        assert stored["rows"] == FRAMES and stored["unmatched"] == 0
        still_rows, still_mean, _ = still_reference(q_arm, q_cmd)
        assert stored["bias_rows"] == still_rows.tolist() and sum(stored["bias_rows"]) <= 2
        np.testing.assert_allclose(stored["bias_mean"], still_mean, rtol=1e-9, atol=1e-12)
        assert not any(stored["biased"])  # random rows: hardly ever still, no flag

    # browse's segments.json row carries them
    site = examples_dir / "out" / "cmd_site"
    browsed = run_cli("browse", str(config), "-o", str(site))
    assert browsed.code == 0, browsed.err
    rows = {row["id"]: row for row in json.loads((site / "segments.json").read_text())["segments"]}
    assert rows["episode_000000"]["diff"] == [{"copy": "cmd", "measured": "arm", "rows": FRAMES, "beyond": 10, "joints": ["elbow_flex"]}]
    assert rows["episode_000001"]["diff"] == [{"copy": "cmd", "measured": "arm", "rows": FRAMES, "beyond": 1, "joints": ["gripper"]}]


def _pair(qa: QaPlan | None = None) -> PairDifferences:
    """A copy `cmd` of `arm` over three revolute joints and one prismatic one, the measured robot's map in another order."""
    channel = dict(source_index=0, source_unit="rad", factor=1.0, sign=1.0, offset=0.0, lower=None, upper=None, slack=0.0, where=None)
    joints = ["a", "b", "c", "slide"]
    plan = dict(
        urdf_path=Path("x.urdf"), urdf_text="", urdf_origin="", urdf_sha256="", robot_name="x", root_link="base", links=(),
        joint_links=(), entity_path_prefix="/x", frame_prefix="", keep_collisions=False, source="s", holds=(), mimics=(),
        on_violation="error", where=None,
    )  # fmt: skip
    copy = RobotPlan(key="cmd", channels=tuple(JointChannel(joint=j, source_name=j, **channel) for j in joints), **plan)
    arm = RobotPlan(key="arm", channels=tuple(JointChannel(joint=j, source_name=j, **channel) for j in reversed(joints)), **plan)
    thresholds = (np.radians(2.0),) * 3 + (0.005,)
    comparison = Comparison("arm", np.radians(2.0), 0.005, "{angle: 2 deg, length: 5 mm}", thresholds, ("deg",) * 3 + ("mm",))
    return PairDifferences(copy, arm, comparison, qa)


def test_differences_match_rows_across_uneven_batches_and_skip_rows_left_out() -> None:
    rng = np.random.default_rng(5)
    measured = rng.uniform(-1, 1, size=(1000, 4))
    commanded = measured + rng.normal(0, 0.03, size=measured.shape)
    left_out = np.zeros(1000, dtype=bool)
    left_out[[3, 500, 999]] = True
    commanded[500] += 10.0  # a row the copy left out: never compared
    pair = _pair()
    for start, stop in ((0, 700), (700, 1000)):  # the copy's batches
        pair.add("cmd", commanded[start:stop], left_out[start:stop])
    for start, stop in ((0, 128), (128, 129), (129, 1000)):  # the measured robot's, its columns in its own order
        pair.add("arm", measured[start:stop, ::-1], None)
    result = pair.result()
    kept = ~left_out
    difference = np.abs(commanded - measured)[kept]
    limits = np.array([np.radians(2.0)] * 3 + [0.005])
    assert result.rows == kept.sum() and result.unmatched == 0
    np.testing.assert_array_equal(result.largest, difference.max(axis=0))
    assert result.beyond == tuple((difference > limits).sum(axis=0).tolist())
    assert result.rows_beyond == int((difference > limits).any(axis=1).sum())
    assert not pair.pending["cmd"][0].size and not pair.pending["arm"][0].size, "everything matched: nothing kept"


def test_differences_survive_the_manifest_and_hand_edits_drop_them() -> None:
    pair = _pair()
    pair.add("cmd", np.zeros((4, 4)), None)
    pair.add("arm", np.full((3, 4), 0.1), None)
    result = pair.result()
    assert result.unmatched == 1 and result.rows == 3 and result.joints_beyond == ("a", "b", "c", "slide")
    assert JointDifferences.from_json(json.loads(json.dumps(result.as_json()))) == result
    assert (result.largest_text(0), result.largest_text(3)) == ("5.73 deg", "100 mm")
    assert JointDifferences.from_json({**result.as_json(), "units": ["deg"]}).largest_text(0) == "0.1"  # type: ignore[union-attr]
    for edit in ({"beyond": [1, 2]}, {"largest": ["x", 0, 0, 0]}, {"rows": -1}, {"copy": 3}, {"joints": []}, {"beyond": [True, 0, 0, 0]}):
        assert JointDifferences.from_json({**result.as_json(), **edit}) is None, edit
    assert JointDifferences.from_json({**result.as_json(), "copy": "a\nb" + "x" * 500}).copy.startswith("a")


def test_appearance_changes_the_models_hash_and_compare_the_segments(examples_dir: Path) -> None:
    """A colour changed rewrites the split layout's model; a threshold changed rewrites the layers (their summaries);
    a config without either keeps the model hash it had."""
    plan = compile_config(examples_dir / "so101_dataset.yaml")
    robot = plan.robots[0]
    coloured = replace(plan, robots=(replace(robot, appearance=(1.0, 0.5, 0.0, 0.4)),))
    assert model_hash(coloured) != model_hash(plan)
    assert model_hash(replace(plan, robots=(replace(robot, appearance=None),))) == model_hash(plan)
    compared = replace(plan, robots=(replace(robot, compare=Comparison("other", 0.1, 0.01, "{angle: 0.1 rad, length: 1 cm}")),))
    assert segment_hashes(compared, False) != segment_hashes(plan, False)


def test_plan_shows_the_copy_and_diff_its_changes(examples_dir: Path, erd_share: Path, run_cli) -> None:
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    measured, commanded = episodes(reference)
    write_commanded_dataset(examples_dir / "data" / "cmd_plan", [np.degrees(q) for q in measured], [np.degrees(q) for q in commanded])
    old = commanded_config(examples_dir, "cmd_plan_old", "data/cmd_plan")
    new = commanded_config(
        examples_dir, "cmd_plan_old_edit", "data/cmd_plan", {"appearance": {"color": COLOR}, "compare": {"robot": "arm"}}
    )
    text = run_cli("plan", str(old))
    assert text.code == 0, text.err
    assert (
        "  drawn in colour [1, 0.5, 0] at opacity 0.4; a copy compared with robot 'arm', threshold {angle: 2 deg, length: 5 mm}" in text.out
    )
    report = json.loads(run_cli("plan", "--format", "json", str(old)).out)
    robots = {robot["key"]: robot for robot in report["robots"]}
    assert robots["cmd"]["appearance"] == {"color": COLOR, "opacity": OPACITY}
    assert robots["cmd"]["compare"] == {"robot": "arm", "threshold": "{angle: 2 deg, length: 5 mm}"}
    assert "appearance" not in robots["arm"] and "compare" not in robots["arm"]
    diff = run_cli("diff", str(old), str(new))
    assert "robot cmd: appearance [1, 0.5, 0, 0.4] -> [1, 0.5, 0, 1]" in diff.out
    assert "robot cmd: compare arm {angle: 2 deg, length: 5 mm} -> arm {angle: 1 deg, length: 1 mm}" in diff.out  # the defaults


def _still_and_moving(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """1000 rows: still in 0..399 and 700..999 (sensor noise only), moving fast in between; the copy is offset by 3 deg
    on `a` (beyond qa.bias's 2 deg), 1 deg on `b` (within), and 3 mm on `slide` (beyond 2 mm)."""
    measured = np.zeros((1000, 4))
    measured[400:700] = np.linspace(0.0, 30.0, 300)[:, None]  # 0.1 per row: far above any still step
    measured += rng.normal(0, 1e-4, size=measured.shape)
    commanded = measured + np.array([np.radians(3.0), np.radians(1.0), 0.0, 0.003]) + rng.normal(0, 1e-4, size=measured.shape)
    return measured, commanded


def test_calibration_bias_equals_numpy_over_the_rows_both_robots_are_still() -> None:
    measured, commanded = _still_and_moving(np.random.default_rng(8))
    left_out = np.zeros(1000, dtype=bool)
    left_out[[100, 900]] = True
    pair = _pair()
    for start, stop in ((0, 333), (333, 1000)):
        pair.add("cmd", commanded[start:stop], left_out[start:stop])
    for start, stop in ((0, 1), (1, 650), (650, 1000)):
        pair.add("arm", measured[start:stop, ::-1], None)
    result = pair.result()
    # numpy reference: a row is still at a joint when both sides' step from the row before is below the static velocity
    # (5 deg/s, 5 mm/s) times 1 s, neither row left out
    copy = np.where(left_out[:, None], np.nan, commanded)
    limit = np.array([np.radians(5.0)] * 3 + [0.005])
    with np.errstate(invalid="ignore"):
        still = (np.abs(np.diff(copy, axis=0)) < limit) & (np.abs(np.diff(measured, axis=0)) < limit)
    still = np.vstack([np.zeros((1, 4), dtype=bool), still])
    difference = commanded - measured
    assert result.bias_rows == tuple(still.sum(axis=0).tolist())
    assert 0 < result.bias_rows[0] < 700
    for joint in range(4):
        values = difference[still[:, joint], joint]
        np.testing.assert_allclose(result.bias_mean[joint], values.mean(), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(result.bias_std[joint], values.std(), rtol=1e-6, atol=1e-12)
    assert result.biased == (True, False, False, True) and result.joints_biased == ("a", "slide")
    assert JointDifferences.from_json(json.loads(json.dumps(result.as_json()))) == result
    # a higher threshold flags nothing; an older manifest's entry (no bias) still reads back
    relaxed = _pair(replace(QaPlan(), bias=replace(QaPlan().bias, angle=np.radians(4.0), length=0.004)))
    relaxed.add("cmd", commanded, None)
    relaxed.add("arm", measured[:, ::-1], None)
    assert not any(relaxed.result().biased)
    old = {k: v for k, v in result.as_json().items() if not k.startswith("bias")}
    assert JointDifferences.from_json(old) == replace(result, bias_rows=(), bias_mean=(), bias_std=(), biased=())


def test_no_still_rows_give_no_bias_and_no_flag() -> None:
    pair = _pair()
    moving = np.arange(400.0).reshape(100, 4)  # every step 4: never still
    pair.add("cmd", moving + 1.0, None)
    pair.add("arm", moving[:, ::-1], None)
    result = pair.result()
    assert result.bias_rows == (0, 0, 0, 0) and result.bias_mean == (0.0,) * 4 and not any(result.biased)


def biased_episodes(reference: PinocchioRobot) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Two 60-row episodes (30 fps) at the middle of the limits, still (0.01 deg of noise) but for rows 20..39 where
    every joint moves 1.15 deg a row out and back; the copy is off by 3 deg on elbow_flex in episode 0 (beyond qa.bias's
    2 deg), by 1 deg on it in episode 1 (within)."""
    rng = np.random.default_rng(3)
    middle = np.array([reference.limits(j) for j in SO101_JOINTS]).mean(axis=1)
    ramp = np.concatenate([np.zeros(20), np.arange(1, 11) * 0.02, np.arange(9, -1, -1) * 0.02, np.zeros(20)])
    measured, commanded = [], []
    for offset in (3.0, 1.0):
        q = middle + ramp[:, None] + rng.normal(0, np.radians(0.01), size=(60, 6))
        measured.append(q)
        commanded.append(q + np.radians(offset) * (np.arange(6) == 2) + rng.normal(0, np.radians(0.01), size=q.shape))
    return measured, commanded


def still_reference(q_arm: np.ndarray, q_cmd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """numpy's bias on the written (float32, degrees) values: per joint the rows, mean and std of (copy - measured)
    where both robots' step from the row before is below 5 deg/s at 30 fps."""
    written = [np.radians(np.degrees(q).astype(np.float32).astype(np.float64)) for q in (q_arm, q_cmd)]
    still = np.vstack([np.zeros((1, 6), dtype=bool), np.all([np.abs(np.diff(w, axis=0)) < np.radians(5.0) / 30 for w in written], axis=0)])
    difference = written[1] - written[0]
    rows = still.sum(axis=0)
    picked = [difference[still[:, j], j] for j in range(6)]
    return (
        rows,
        np.array([p.mean() if p.size else 0.0 for p in picked]),
        np.array([p.std() if p.size else 0.0 for p in picked]),
    )


def biased_config(examples_dir: Path, erd_share: Path, name: str) -> tuple[Path, list[np.ndarray], list[np.ndarray]]:
    """`biased_episodes` written as a LeRobot dataset and its config (a difference threshold of 5 deg: none beyond)."""
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    measured, commanded = biased_episodes(reference)
    write_commanded_dataset(examples_dir / "data" / name, [np.degrees(q) for q in measured], [np.degrees(q) for q in commanded])
    threshold = {"compare": {"robot": "arm", "threshold": {"angle": "5 deg", "length": "5 mm"}}}
    return commanded_config(examples_dir, name, f"data/{name}", threshold), measured, commanded


def test_calibration_bias_in_run_line_and_manifest(examples_dir: Path, run_cli, erd_share: Path) -> None:
    config, measured, commanded = biased_config(examples_dir, erd_share, "cmd_bias")
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    lines = [line for line in result.err.splitlines() if "'cmd' against 'arm'" in line]
    assert len(lines) == 2, result.err
    assert "within {angle: 5 deg, length: 5 mm}; calibration bias elbow_flex 3 deg (std 0.0" in lines[0], lines[0]
    assert "calibration bias" not in lines[1]
    manifest = json.loads((examples_dir / "out" / "cmd_bias" / "cmd_bias.manifest.json").read_text())
    summaries = {entry["segment"]: entry["summary"] for entry in manifest["segments"]}
    for episode, (q_arm, q_cmd) in enumerate(zip(measured, commanded, strict=True)):
        stored = summaries[f"episode_{episode:06d}"]["differences"][0]
        rows, mean, std = still_reference(q_arm, q_cmd)
        assert stored["bias_rows"] == rows.tolist() and 35 <= rows.min() and rows.max() <= 40
        np.testing.assert_allclose(stored["bias_mean"], mean, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(stored["bias_std"], std, rtol=1e-6, atol=1e-12)
        assert stored["biased"] == [episode == 0 and j == 2 for j in range(6)]
    # browse's segments.json row names the biased joint with its mean in the threshold's unit; none within qa.bias
    site = examples_dir / "out" / "cmd_bias_site"
    browsed = run_cli("browse", str(config), "-o", str(site))
    assert browsed.code == 0, browsed.err
    rows = {row["id"]: row for row in json.loads((site / "segments.json").read_text())["segments"]}
    assert rows["episode_000000"]["diff"] == [
        {"copy": "cmd", "measured": "arm", "rows": 60, "beyond": 0, "joints": [], "bias": ["elbow_flex 3 deg"]}
    ]
    assert "bias" not in rows["episode_000001"]["diff"][0]


def test_qa_reports_calibration_bias_and_flags_it(examples_dir: Path, run_cli, erd_share: Path) -> None:
    config, measured, commanded = biased_config(examples_dir, erd_share, "cmd_bias_qa")
    report = examples_dir / "out" / "cmd_bias_qa.json"
    result = run_cli("qa", str(config), "--format", "json", "-o", str(report))
    assert result.code == 0, result.err
    segments = json.loads(report.read_text())["segments"]
    for episode, segment in enumerate(segments):
        rows, mean, std = still_reference(measured[episode], commanded[episode])
        bias = segment["bias"]
        assert list(bias) == [f"cmd/{joint}" for joint in SO101_JOINTS]
        assert [b["rows"] for b in bias.values()] == rows.tolist()
        np.testing.assert_allclose([b["mean"] for b in bias.values()], mean, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose([b["std"] for b in bias.values()], std, rtol=1e-6, atol=1e-12)
        assert ("calibration_bias" in segment["flags"]) == (episode == 0), segment["flags"]
    gated = run_cli("qa", str(config), "--fail-on", "calibration_bias")
    assert gated.code == 1 and "episode_000000" in gated.err + gated.out and "episode_000001" not in gated.err, gated.err

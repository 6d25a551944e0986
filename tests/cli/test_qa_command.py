"""`urdf-pipeline qa` on a LeRobot v3 dataset of teleoperation-like Panda episodes with planted faults: the json
numbers equal a numpy reference on the corrected values, each fault is flagged on its segment only, --fail-on exits 1
naming them, --exclusions lists their episodes, hostile names stay inert in markdown and github, and a refused config
writes nothing."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest
import yaml

from urdf_pipeline import cli
from urdf_pipeline.execute.qa_metrics import JERK_PRECISION
from urdf_pipeline.review import render_qa

from ..lerobot_layouts import lerobot_panda_config, write_v3_dataset
from ..source_helpers import PANDA_JOINTS

DEG = math.pi / 180
FPS = 30
CENTRE = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.8, 0.0, 0.02])
AMPLITUDE = np.array([20, 20, 20, 20, 20, 20, 20, 0]) * DEG + np.array([0] * 7 + [0.01])
FAULTS = {1: ["spike"], 3: ["static"], 5: ["length_outlier"], 7: ["timestamp_gap"], 9: ["timestamp_order"]}


def teleoperation(rng: np.random.Generator, rows: int, moving: bool = True) -> np.ndarray:
    t = np.arange(rows)[:, None] / FPS
    frequency, phase = rng.uniform(0.1, 0.5, 8), rng.uniform(0, 2 * math.pi, 8)
    noise = rng.normal(0, 1, (rows, 8)) * np.array([0.05 * DEG] * 7 + [0.00005])
    return CENTRE + (AMPLITUDE if moving else 0) * np.sin(2 * math.pi * frequency * t + phase) + noise


def _retime(root: Path, episode: int, change: str) -> None:
    """A gap of 4 frames after frame 200 (every later timestamp moved), or frame 250's timestamp before frame 249's."""
    path = root / "data" / "chunk-000" / f"file-{episode // 2:03d}.parquet"
    table = pq.read_table(path)
    stamps = table.column("timestamp").to_numpy().copy()
    rows = np.flatnonzero(pc.equal(table.column("episode_index"), episode).to_numpy(zero_copy_only=False))
    if change == "gap":
        stamps[rows[200:]] += np.float32(4 / FPS)
    else:
        stamps[rows[250]] = stamps[rows[249]] - np.float32(0.001)
    table = table.set_column(table.schema.get_field_index("timestamp"), "timestamp", pa.array(stamps, pa.float32()))
    pq.write_table(table, path)


@pytest.fixture(scope="module")
def dataset(examples_dir: Path) -> tuple[Path, list[np.ndarray]]:
    rng = np.random.default_rng(5)
    episodes = [teleoperation(rng, int(20 * FPS * rng.uniform(0.85, 1.15))) for _ in range(12)]
    episodes[1][300, 2] += 40 * DEG  # a one-frame 40 deg jump
    episodes[3] = teleoperation(rng, len(episodes[3]), moving=False)
    episodes[5] = teleoperation(rng, 3 * int(np.median([len(e) for e in episodes])))
    root = examples_dir / "data" / "qa_lerobot"
    write_v3_dataset(root, episodes, PANDA_JOINTS)
    _retime(root, 7, "gap")
    _retime(root, 9, "order")
    config = lerobot_panda_config(examples_dir, "qa_lerobot", {"lerobot": "data/qa_lerobot", "feature": "observation.state"})
    return config, [e.astype(np.float32).astype(np.float64) for e in episodes]


def _qa(capsys: pytest.CaptureFixture[str], *words: str) -> tuple[int, str, str]:
    code = cli.main(["qa", *words])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_numbers_equal_the_numpy_reference_and_each_fault_is_flagged_on_its_segment(
    dataset: tuple[Path, list[np.ndarray]], capsys: pytest.CaptureFixture[str]
) -> None:
    config, episodes = dataset
    code, out, _ = _qa(capsys, str(config), "--format", "json")
    assert code == 0
    data = json.loads(out)
    assert data["version"] == 1
    assert [s["flags"] for s in data["segments"]] == [FAULTS.get(i, []) for i in range(12)]
    assert data["summary"] == {"segments": 12, "flagged": 5, "by_flag": {f[0]: 1 for f in FAULTS.values()}}
    for index in (0, 1, 3):  # clean, spiked, still: times are frame / fps, as the dataset's timestamps say
        segment, values = data["segments"][index], episodes[index]
        steps = np.diff((np.arange(len(values)) / FPS).astype(np.float32).astype(np.float64))
        velocity = np.diff(values, axis=0) / steps[:, None]
        jerk = np.diff(np.diff(velocity, axis=0) / steps[1:, None], axis=0) / steps[2:, None]
        assert segment["rows"] == len(values)
        assert segment["duration_s"] == pytest.approx((len(values) - 1) / FPS, rel=1e-6)
        assert set(segment) == {"id", "rows", "duration_s", "flags", "joints", "timing", "bias"}
        for j, name in enumerate(PANDA_JOINTS):
            joint = segment["joints"][name]
            assert joint["max_abs_velocity"] == pytest.approx(np.abs(velocity[:, j]).max(), rel=1e-5)
            assert joint["p95_abs_jerk"] == pytest.approx(np.percentile(np.abs(jerk[:, j]), 95), rel=2 * JERK_PRECISION)
            static = 5 * DEG if name != "panda_finger_joint1" else 0.005
            assert joint["static_fraction"] == pytest.approx(np.mean(np.abs(velocity[:, j]) < static), abs=2 / len(values))
        assert segment["timing"]["gaps"] == 0 and segment["timing"]["order_violations"] == 0
    assert data["segments"][7]["timing"]["max_gap_s"] == pytest.approx(5 / FPS, rel=1e-5)
    assert data["segments"][9]["timing"]["order_violations"] == 1
    code, out, _ = _qa(capsys, str(config), "--format", "github")
    config_file = config.as_posix().replace(":", "%3A").replace(",", "%2C")
    expected = [f"::warning file={config_file}::segment 'episode_{i:06d}': {FAULTS[i][0]}" for i in sorted(FAULTS)]
    assert code == 0 and out.splitlines() == expected


def test_fail_on_exits_1_naming_the_segments_and_exclusions_list_the_episodes(
    dataset: tuple[Path, list[np.ndarray]], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config, _ = dataset
    report, exclusions = tmp_path / "qa.md", tmp_path / "excluded.json"
    code, out, err = _qa(capsys, str(config), "--fail-on", "spike,static", "-o", str(report), "--exclusions", str(exclusions))
    assert code == 1 and out == ""
    assert err.count("error:") == 1
    assert "'episode_000001' (spike)" in err and "'episode_000003' (static)" in err and "episode_000005" not in err
    assert json.loads(exclusions.read_text()) == sorted(FAULTS)
    text = report.read_text()  # the text report, written whole although the gate failed
    assert "episode_000009: 641 rows, 21.333 s, timestamp_order\n" in text and "5 of 12 segment(s) flagged" in text
    code, _, err = _qa(capsys, str(config), "--fail-on", "spikes")
    assert code == 1 and "unknown flag 'spikes' (did you mean 'spike'?)" in err


def test_the_config_fail_on_is_the_default(
    dataset: tuple[Path, list[np.ndarray]], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config, _ = dataset
    data = yaml.safe_load(config.read_text())
    data["qa"] = {"fail_on": ["timestamp_gap"]}
    gated = config.with_name("qa_gated.yaml")
    gated.write_text(yaml.safe_dump(data, sort_keys=False))
    code, _, err = _qa(capsys, str(gated), "--episodes", "6:8")
    assert code == 1 and "'episode_000007' (timestamp_gap)" in err
    assert _qa(capsys, str(gated), "--episodes", "6:8", "--fail-on", "")[0] == 0


def test_a_refused_config_writes_no_file(
    dataset: tuple[Path, list[np.ndarray]], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config, _ = dataset
    data = yaml.safe_load(config.read_text())
    data["qa"] = {"static_velocity": "5 mm"}  # a length, not a velocity
    refused = config.with_name("qa_refused.yaml")
    refused.write_text(yaml.safe_dump(data, sort_keys=False))
    report, exclusions = tmp_path / "qa.json", tmp_path / "excluded.json"
    code, _, err = _qa(capsys, str(refused), "-o", str(report), "--exclusions", str(exclusions))
    assert code == 1 and "static_velocity" in err
    assert not report.exists() and not exclusions.exists()


HOSTILE = "ep\n::error::forged|`<b>*x*</b>%0A"


def test_hostile_names_stay_inert_in_markdown_and_github() -> None:
    joint = {"max_abs_velocity": 1.0, "p95_abs_jerk": 2.0, "static_fraction": 0.5}
    timing = {"max_gap_s": 0.1, "gaps": 1, "order_violations": 0}
    segment = {"id": HOSTILE, "rows": 10, "duration_s": 0.3, "flags": ["spike"], "joints": {HOSTILE: joint}, "timing": timing, "bias": {}}
    data = {"version": 1, "segments": [segment], "summary": {"segments": 1, "flagged": 1, "by_flag": {"spike": 1}}}
    markdown = render_qa(data, "markdown", "c.yaml")
    inert = "``ep\\n::error::forged\\|`<b>*x*</b>%0A``"  # a code span: newline shown as \n, the table's `|` escaped
    assert markdown.splitlines()[-1] == f"| {inert} | 10 | 0.300 s | spike | {inert} 2 |"
    github = render_qa(data, "github", "c.yaml")
    assert github == "::warning file=c.yaml::segment 'ep\\n::error::forged|`<b>*x*</b>%250A': spike\n"


def test_a_source_without_time_or_fps_has_no_duration_and_is_excluded_by_its_segment_id(
    examples_dir: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """configs/demo.yaml: a parquet file on a sequence index. Each row is a step of 1 s; an absolute jerk bound of
    1e-9 rad/s^3 flags its one segment, listed in the exclusions by its id (it is no LeRobot episode)."""
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    data["qa"] = {"spike": {"factor": 20, "jerk": "0.000000001 rad/s^3"}}
    config = examples_dir / "qa_demo.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    exclusions = tmp_path / "excluded.json"
    code, out, _ = _qa(capsys, str(config), "--format", "json", "--exclusions", str(exclusions))
    segment = json.loads(out)["segments"][0]
    assert code == 0 and segment["duration_s"] is None and segment["timing"]["max_gap_s"] is None
    assert segment["flags"] == ["spike"] and json.loads(exclusions.read_text()) == [segment["id"]]

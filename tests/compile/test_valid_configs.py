"""Every config in configs/ and tests/configs/valid validates and runs; the real G1 recording matches pinocchio."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from rerun.chunk import RrdReader

from urdf_pipeline.confine import ALLOW_ENV
from urdf_pipeline.examples import prepare

from ..conftest import CONFIGS, SHARED
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames, rotation_angle

VALID = Path(__file__).resolve().parents[1] / "configs" / "valid"
G1_DATA = SHARED / "data" / "lerobot_g1_inspire_v21"


@pytest.fixture(autouse=True)
def _allow_shared_data(monkeypatch: pytest.MonkeyPatch) -> None:
    """The real G1 recording is linked in from ../shared, outside the config's folder: the runner allows it, as a user would."""
    monkeypatch.setenv(ALLOW_ENV, str(G1_DATA))


def needs_shared(config: Path) -> bool:
    return "# needs: shared" in config.read_text()


@pytest.fixture(scope="module")
def valid_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("valid")
    prepare(directory, frames=120)
    if G1_DATA.is_dir():
        (directory / "data" / G1_DATA.name).symlink_to(G1_DATA, target_is_directory=True)
    return directory


@pytest.mark.parametrize("config", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_shipped_config_validates_and_runs(config: Path, examples_dir: Path, run_cli) -> None:
    copy = examples_dir / config.name
    assert run_cli("validate", str(copy)).code == 0
    result = run_cli("run", str(copy))
    assert result.code == 0, result.err
    output = yaml.safe_load(copy.read_text())["output"]
    for written in map(Path, result.out.split()):  # one per segment (and the model of a split layout)
        assert written.is_file() and written.stat().st_size > 0
        (store,) = RrdReader(written).recordings()
        assert store.application_id == output["application_id"]
        assert store.recording_id == "urdf_model" if written.name == "model.rrd" else store.recording_id in written.stem
        assert not list(written.parent.glob(".*partial*")), "no partial files are left behind"


@pytest.mark.parametrize("config", sorted(VALID.glob("*.yaml")), ids=lambda p: p.name)
def test_valid_config_validates_and_runs(config: Path, valid_dir: Path, run_cli) -> None:
    if needs_shared(config) and not G1_DATA.is_dir():
        pytest.skip(f"{G1_DATA} is absent (shared data is not part of a fresh clone)")
    copy = valid_dir / config.name
    shutil.copy(config, copy)
    assert run_cli("validate", str(copy)).code == 0
    result = run_cli("run", str(copy))
    assert result.code == 0, result.err
    assert Path(result.out.strip()).is_file()


@pytest.mark.skipif(not G1_DATA.is_dir(), reason=f"{G1_DATA} is absent (shared data is not part of a fresh clone)")
def test_g1_real_recording_matches_pinocchio(valid_dir: Path, run_cli) -> None:
    config = valid_dir / "g1_inspire_lerobot.yaml"
    shutil.copy(VALID / config.name, config)
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert _compare_g1_episode(config, valid_dir, 0, [Path(result.out.strip())]) > 3 * 30


@pytest.mark.skipif(not G1_DATA.is_dir(), reason=f"{G1_DATA} is absent (shared data is not part of a fresh clone)")
def test_g1_dataset_split_layout_model_plus_layers_match_pinocchio(valid_dir: Path, run_cli) -> None:
    """The real dataset, one layer per episode beside one model: each episode's layer with the model gives the right poses."""
    spec = yaml.safe_load((VALID / "g1_inspire_lerobot.yaml").read_text())
    del spec["sources"]["g1_state"]["episode"]
    spec["output"] = {
        "layout": "split",
        "model": "out/g1_dataset/model.rrd",
        "path": "out/g1_dataset/{segment}.rrd",
        "segment": "episode_{episode:06d}",
        "episodes": [3, 57, 99],
        "application_id": "g1_inspire",
    }
    config = valid_dir / "g1_dataset.yaml"
    config.write_text(yaml.safe_dump(spec, sort_keys=False))
    result = run_cli("run", str(config), "--jobs", "2")
    assert result.code == 0, result.err
    out = valid_dir / "out" / "g1_dataset"
    for episode in (3, 57, 99):
        assert _compare_g1_episode(config, valid_dir, episode, [out / "model.rrd", out / f"episode_{episode:06d}.rrd"]) > 3 * 30


def _compare_g1_episode(config: Path, valid_dir: Path, episode: int, recordings: list[Path]) -> int:
    """Poses of every G1 link at three frames of one episode: the recording(s) against pinocchio on the data itself."""
    g1 = yaml.safe_load(config.read_text())["robots"]["g1"]
    urdf = (valid_dir / g1["urdf"]).resolve()
    names = _feature_names(G1_DATA)
    data = G1_DATA / "data" / "chunk-000" / f"episode_{episode:06d}.parquet"
    values = np.array(pq.read_table(data, columns=["observation.state"]).column(0).to_pylist())
    reference = PinocchioRobot(urdf)
    frames = read_frames(recordings, "frame_index")
    root = _urdf_root(urdf)
    compared = 0
    for frame in (0, len(values) // 2, len(values) - 1):
        joint_values = {joint: float(values[frame, names.index(name)]) for name, joint in g1["joints"]["map"].items()}
        joint_values.update(g1["joints"]["hold"])
        for link, expected in reference.link_poses(joint_values).items():
            if link == root:
                continue
            recorded = frames.world_pose(link, frame, root)
            assert np.linalg.norm(recorded[:3, 3] - expected[:3, 3]) < 1e-5, f"{link} at frame {frame} of episode {episode}"
            assert rotation_angle(recorded, expected) < 1e-5, f"{link} at frame {frame} of episode {episode}"
            compared += 1
    return compared


def _feature_names(dataset: Path) -> list[str]:
    import json

    names = json.loads((dataset / "meta" / "info.json").read_text())["features"]["observation.state"]["names"]
    return names[0] if isinstance(names[0], list) else names


def _urdf_root(urdf: Path) -> str:
    import xml.etree.ElementTree as ET

    robot = ET.parse(urdf).getroot()
    children = {j.find("child").get("link") for j in robot.findall("joint")}
    return next(link.get("name") for link in robot.findall("link") if link.get("name") not in children)

"""HDF5 sources: ALOHA's layout, one [rows, values] dataset holding both arms, read with Rerun's Hdf5Reader."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import yaml

from ..execute.test_fk_against_pinocchio import check_robot, panda_joint_values
from ..rrd_frames import read_frames
from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, panda_reference, random_panda_q

LEFT = [f"left_{n}" for n in PANDA_JOINTS]
RIGHT = [f"right_{n}" for n in PANDA_JOINTS]


def write_aloha_episode(path: Path, qpos: np.ndarray, time_s: np.ndarray | None = None) -> None:
    """ALOHA's episode layout: /observations/{qpos,qvel,images/cam_high}, /action; plus datasets that must not be read."""
    rows = len(qpos)
    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as file:
        file.attrs["sim"] = False
        observations = file.create_group("observations")
        observations.create_dataset("qpos", data=qpos)
        observations.create_dataset("qvel", data=np.zeros_like(qpos))
        observations.create_group("images").create_dataset("cam_high", data=np.zeros((rows, 24, 32, 3), np.uint8))
        file.create_dataset("action", data=np.zeros((rows + 3, qpos.shape[1]), np.float32))  # a different length: must be ignored
        if time_s is not None:
            observations.create_dataset("time", data=time_s)
            observations.create_dataset("frame", data=np.arange(rows) * 2)


def bimanual_config(directory: Path, segment: str, source: dict[str, Any]) -> Path:
    def robot(prefix: str, names: list[str]) -> dict[str, Any]:
        joint_map: dict[str, Any] = dict(zip(names[:7], PANDA_JOINTS[:7], strict=True))
        joint_map[names[7]] = {"joint": "panda_finger_joint1", "unit": "m"}
        return {
            "urdf": "robots/panda.urdf",
            "package_paths": {"example-robot-data": "robots/share/example-robot-data"},
            "frame_prefix": prefix,
            "joints": {"source": "aloha", "map": joint_map, "ignore": [n for n in LEFT + RIGHT if n not in names]},
        }

    data = {
        "version": 1,
        "sources": {"aloha": source},
        "robots": {"left": robot("left_", LEFT), "right": robot("right_", RIGHT)},
        "frames": {"root": "world"},
        "edges": [
            {"parent": "world", "child": "left_panda_link0", "translation": [0.0, 0.3, 0.0], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]},
            {"parent": "world", "child": "right_panda_link0", "translation": [0.0, -0.3, 0.0], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]},
        ],
        "output": {"path": "out/sources/{segment}.rrd", "application_id": "sources_test", "segment": segment},
    }
    path = directory / f"{segment}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def test_aloha_layout_drives_two_arms_and_matches_pinocchio(examples_dir: Path, run_cli) -> None:
    left, right = random_panda_q(examples_dir, 40, seed=41), random_panda_q(examples_dir, 40, seed=42)
    write_aloha_episode(examples_dir / "data" / "episode_0.hdf5", np.concatenate([left, right], axis=1))
    source = {"hdf5": "data/episode_0.hdf5", "dataset": "/observations/qpos", "names": LEFT + RIGHT}
    config = bimanual_config(examples_dir, "hdf5_aloha", source)
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "row_index")  # no index: Rerun's generated row timeline
    reference = panda_reference(examples_dir)
    for prefix, q, y in (("left_", left, 0.3), ("right_", right, -0.3)):
        world_from_base = np.eye(4)
        world_from_base[:3, 3] = [0.0, y, 0.0]
        values = [panda_joint_values(row) for row in q]
        assert check_robot(frames, list(range(40)), reference, values, prefix, world_from_base, "world", [0, 17, 39]) == 3 * 13


@pytest.mark.parametrize(
    ("index", "timeline", "times"),
    [
        ({"timestamp": "/observations/time", "unit": "s"}, "time", [1_700_000_000_000_000_000 + i * 20_000_000 for i in range(12)]),
        ("observations/frame", "frame", [i * 2 for i in range(12)]),
    ],
    ids=["timestamp", "sequence"],
)
def test_index_dataset_becomes_the_timeline(examples_dir: Path, run_cli, index: Any, timeline: str, times: list[int]) -> None:
    q = random_panda_q(examples_dir, 12, seed=43)
    write_aloha_episode(examples_dir / "data" / "timed.hdf5", q, time_s=1_700_000_000 + np.arange(12) * 0.02)
    source = {"hdf5": "data/timed.hdf5", "dataset": "observations/qpos", "names": PANDA_JOINTS, "index": index}
    result = run_cli("run", str(panda_config(examples_dir, f"hdf5_index_{timeline}", source)))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), timeline, times, q, [0, 11])


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            {"dataset": "/observations/qpoz"},
            "no dataset '/observations/qpoz' in checks.hdf5; its 2-D datasets: /action, /observations/qpos",
        ),
        ({"dataset": "/observations/images/cam_high"}, "dataset '/observations/images/cam_high' has shape [5, 24, 32, 3]"),
        ({"names": [f"j{i}" for i in range(24)]}, "dataset '/observations/qpos' holds 26 values per row but 24 names are given"),
        ({"index": "/observations/time"}, "index dataset '/observations/time' holds float64; a sequence timeline needs integers"),
        ({"index": "/action"}, "index dataset '/action' has shape [8, 26]"),
        ({"index": {"duration": "/observations/nothing"}}, "no index dataset '/observations/nothing' in checks.hdf5"),
        ({"hdf5": "data/not.hdf5"}, "cannot open HDF5 file"),
    ],
    ids=["missing", "3-D", "26-values-24-names", "float-sequence", "2-D-index", "missing-index", "not-hdf5"],
)
def test_validate_refuses_from_metadata(examples_dir: Path, run_cli, change: dict[str, Any], expected: str) -> None:
    write_aloha_episode(examples_dir / "data" / "checks.hdf5", np.zeros((5, 26)), time_s=np.arange(5) * 0.02)
    (examples_dir / "data" / "not.hdf5").write_text("not hdf5")
    names = [f"j{i}" for i in range(26)]
    source = {"hdf5": "data/checks.hdf5", "dataset": "/observations/qpos", "names": names, **change}
    result = run_cli("validate", str(panda_config(examples_dir, "hdf5_checks", source, joint_map={"j0": "panda_joint1"})))
    assert result.code == 1
    assert expected in result.err, result.err
    assert "Traceback" not in result.err


def test_index_length_must_match_rows(examples_dir: Path, run_cli) -> None:
    path = examples_dir / "data" / "short_index.hdf5"
    write_aloha_episode(path, np.zeros((5, 8)))
    with h5py.File(path, "a") as file:
        file.create_dataset("t", data=np.arange(4) * 0.1)
    source = {"hdf5": "data/short_index.hdf5", "dataset": "/observations/qpos", "names": PANDA_JOINTS, "index": {"timestamp": "t"}}
    result = run_cli("validate", str(panda_config(examples_dir, "hdf5_short_index", source)))
    assert result.code == 1
    assert "index dataset '/t' has 4 values but the joint dataset has 5 rows" in result.err

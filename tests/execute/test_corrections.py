"""Corrections real data needs, end to end and checked against pinocchio: wrap, source_range, one value
driving several joints, scale, and NaN policies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet

from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames, rotation_angle

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

ARM = [f"panda_joint{i}" for i in range(1, 8)]


def test_wrap_source_range_shared_value_scale_and_hold_last(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    # A Panda URDF without <mimic>: one gripper value must drive both fingers.
    urdf = tmp_path / "panda_no_mimic.urdf"
    urdf.write_text((examples_dir / "robots" / "panda.urdf").read_text().replace('<mimic joint="panda_finger_joint1"/>', ""))
    reference = PinocchioRobot(urdf)
    rng = np.random.default_rng(21)
    frames = 50
    bounds = np.array([reference.limits(j) for j in ARM])
    q = rng.uniform(bounds[:, 0], bounds[:, 1], size=(frames, 7))
    percent = rng.uniform(0, 100, size=frames)
    raw = np.empty((frames, 8))
    raw[:, 0] = np.mod(np.degrees(q[:, 0]), 360.0)  # a servo reporting 0..360
    raw[:, 1:7] = np.degrees(q[:, 1:7]) / 2.0  # logged at half scale
    raw[:, 7] = percent
    raw[10:13, 4] = np.nan  # a dropout in j5: hold the last valid value
    write_joint_parquet(tmp_path / "data.parquet", raw)
    config = {
        "version": 1,
        "sources": {
            "s": {
                "parquet": "data.parquet",
                "column": "observation.state",
                "index": "frame_index",
                "names": [*(f"j{i}" for i in range(1, 8)), "grip"],
            }
        },
        "robots": {
            "arm": {
                "urdf": "panda_no_mimic.urdf",
                "package_paths": {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")},
                "joints": {
                    "source": "s",
                    "unit": "deg",
                    "nan": "hold_last",
                    "map": {
                        "j1": {"joint": "panda_joint1", "wrap": 360},
                        **{f"j{i}": {"joint": f"panda_joint{i}", "scale": 2.0} for i in range(2, 8)},
                        "grip": {"joint": ["panda_finger_joint1", "panda_finger_joint2"], "source_range": [0, 100]},
                    },
                },
            }
        },
        "output": {"path": "out/{segment}.rrd", "application_id": "corrections", "segment": "corrections"},
    }
    path = tmp_path / "corrections.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    result = run_cli("run", str(path))
    assert result.code == 0, result.err
    assert "filled 3 of 50 rows with the last valid values" in result.err
    recorded = read_frames(Path(result.out.strip()), "frame_index")
    expected_q = q.copy()
    expected_q[10:13, 4] = q[9, 4]
    for frame in (0, 11, 12, 13, 49):
        values = dict(zip(ARM, expected_q[frame], strict=True))
        values["panda_finger_joint1"] = values["panda_finger_joint2"] = percent[frame] / 100.0 * 0.04
        for link, pose in reference.link_poses(values).items():
            got = recorded.world_pose(link, frame, "panda_link0")
            assert np.linalg.norm(got[:3, 3] - pose[:3, 3]) < 1e-5, f"{link} at {frame}"
            assert rotation_angle(got, pose) < 1e-5, f"{link} at {frame}"


def test_drop_row_logs_nothing_for_bad_rows(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    raw = np.zeros((20, 8))
    raw[:, 3] = -90.0  # panda_joint4 must be negative
    raw[5, 0] = np.nan
    write_joint_parquet(tmp_path / "nan.parquet", raw)
    data["sources"]["arm_state"]["parquet"] = str(tmp_path / "nan.parquet")
    data["robots"]["arm"]["urdf"] = str(examples_dir / "robots" / "panda.urdf")
    data["robots"]["arm"]["package_paths"]["example-robot-data"] = str(examples_dir / "robots" / "share" / "example-robot-data")
    data["robots"]["arm"]["joints"]["map"]["j3"] = "panda_joint3"
    data["robots"]["arm"]["joints"]["nan"] = "drop_row"
    path = tmp_path / "drop.yaml"
    path.write_text(yaml.safe_dump(data))
    result = run_cli("run", str(path))
    assert result.code == 0, result.err
    assert "left out 1 of 20 rows" in result.err
    recorded = read_frames(Path(result.out.strip()), "frame_index")
    assert 5 not in recorded.temporal["panda_link1"] and 4 in recorded.temporal["panda_link1"]

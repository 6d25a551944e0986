"""Shared by the source tests: a Panda config around any source, and the FK check of its recording against pinocchio."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .execute.test_fk_against_pinocchio import check_robot, panda_joint_values, random_within_limits
from .reference_fk import PinocchioRobot
from .rrd_frames import read_frames

PANDA_JOINTS = [*(f"panda_joint{i}" for i in range(1, 8)), "panda_finger_joint1"]
PANDA_MAP: dict[str, Any] = {
    **{name: name for name in PANDA_JOINTS[:7]},
    "panda_finger_joint1": {"joint": "panda_finger_joint1", "unit": "m"},
}


def panda_reference(examples_dir: Path) -> PinocchioRobot:
    return PinocchioRobot(examples_dir / "robots" / "panda.urdf")


def random_panda_q(examples_dir: Path, frames: int, seed: int) -> np.ndarray:
    """(frames x 8) radians / metres within the Panda's limits, in PANDA_JOINTS order."""
    return random_within_limits(panda_reference(examples_dir), PANDA_JOINTS, frames, seed)


def panda_config(
    directory: Path, segment: str, source: dict[str, Any], joint_map: dict[str, Any] | None = None, ignore: list[str] | None = None
) -> Path:
    """A config in `directory` (the examples dir: robots/ is there) driving one Panda from `source`."""
    joints: dict[str, Any] = {"source": "state", "map": joint_map or PANDA_MAP}
    if ignore:
        joints["ignore"] = ignore
    data = {
        "version": 1,
        "sources": {"state": source},
        "robots": {
            "arm": {
                "urdf": "robots/panda.urdf",
                "package_paths": {"example-robot-data": "robots/share/example-robot-data"},
                "joints": joints,
            }
        },
        "frames": {"root": "world"},
        "edges": [{"parent": "world", "child": "panda_link0", "translation": [0.0, 0.0, 0.5], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]}],
        "output": {"path": "out/sources/{segment}.rrd", "application_id": "sources_test", "segment": segment},
    }
    path = directory / f"{segment}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def assert_panda_fk(
    examples_dir: Path, recording: Path | list[Path], timeline: str, times: list[int], q: np.ndarray, checked: list[int]
) -> None:
    """Link poses in the recording at times[i] equal pinocchio's for q[i] (radians / metres in PANDA_JOINTS order)."""
    frames = read_frames(recording, timeline)
    recorded_times = sorted({t for by_time in frames.temporal.values() for t in by_time})
    assert recorded_times == sorted(times), f"timeline {timeline}: {recorded_times[:5]}... != {sorted(times)[:5]}..."
    world_from_base = np.eye(4)
    world_from_base[:3, 3] = [0.0, 0.0, 0.5]
    values = [panda_joint_values(row) for row in q]
    compared = check_robot(frames, times, panda_reference(examples_dir), values, "", world_from_base, "world", checked)
    assert compared == len(checked) * 13

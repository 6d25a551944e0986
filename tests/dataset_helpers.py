"""Helpers for dataset runs: an isolated copy of the examples, multi-episode LeRobot data, and recording content."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import yaml
from rerun.chunk import RrdReader

from urdf_pipeline.examples import write_lerobot_dataset

from .reference_fk import PinocchioRobot

SO101_JOINTS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def isolated_examples(examples_dir: Path, target: Path, config: str = "so101_dataset.yaml") -> Path:
    """A directory whose robots/ and data/ are the session's examples but whose outputs are its own."""
    target.mkdir(parents=True, exist_ok=True)
    (target / "robots").symlink_to(examples_dir / "robots", target_is_directory=True)
    (target / "data").mkdir()
    for entry in (examples_dir / "data").iterdir():
        (target / "data" / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    shutil.copy(examples_dir / config, target / config)
    return target / config


def random_so101_episodes(reference: PinocchioRobot, lengths: list[int], seed: int) -> list[np.ndarray]:
    """Joint values in radians, uniformly inside the URDF limits, one array per episode."""
    rng = np.random.default_rng(seed)
    bounds = np.array([reference.limits(j) for j in SO101_JOINTS])
    return [rng.uniform(bounds[:, 0], bounds[:, 1], size=(n, len(SO101_JOINTS))) for n in lengths]


def write_so101_dataset(root: Path, episodes_rad: list[np.ndarray]) -> None:
    if root.exists():
        shutil.rmtree(root)
    write_lerobot_dataset(root, [np.degrees(q) for q in episodes_rad], SO101_JOINTS)


def edit_config(config: Path, edit) -> Path:
    data = yaml.safe_load(config.read_text())
    edit(data)
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    return config


def recording_content(path: Path) -> list[tuple[str, bool, list[dict]]]:
    """What a recording holds, independent of chunk and row ids (random per write): to compare two writes."""
    content = []
    for chunk in RrdReader(path).stream().to_chunks():
        table = chunk.to_record_batch()
        columns = [name for name in table.schema.names if name != "rerun.controls.RowId"]
        content.append((chunk.entity_path, chunk.is_static, table.select(columns).to_pylist()))
    return sorted(content, key=lambda item: (item[0], item[1], repr(item[2])[:200]))


def store_ids(path: Path) -> tuple[str, str]:
    (entry,) = RrdReader(path).recordings()
    return str(entry.application_id), str(entry.recording_id)


def status_lines(err: str) -> dict[str, str]:
    """segment -> status, from the summary table."""
    found = {}
    for line in err.splitlines():
        parts = line.split()
        if len(parts) >= 4 and parts[1].replace(",", "").isdigit() and parts[3] in ("written", "skipped", "failed", "bug", "interrupted"):
            found[parts[0]] = parts[3]
    return found

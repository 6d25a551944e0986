"""`output.joint_series` compiled into the plan: the dataset's flag, each segment's recording, never the model; a
config whose robots no source drives is warned that the option plots nothing."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.compile import compile_config
from urdf_pipeline.dataset.fingerprint import model_hash, segment_hashes
from urdf_pipeline.examples import write_joint_parquet

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs in tmp_path read the session's examples

SCENE = """<?xml version="1.0"?>
<robot name="scene">
  <link name="table"/><link name="mount"/>
  <joint name="mount" type="fixed"><parent link="table"/><child link="mount"/><origin xyz="0.5 0 0.6"/></joint>
</robot>
"""


def _example(examples_dir: Path, tmp_path: Path, name: str, output: dict) -> Path:
    data = yaml.safe_load((examples_dir / name).read_text())
    for source in data["sources"].values():
        for kind in ("parquet", "lerobot"):
            if kind in source:
                source[kind] = str(examples_dir / source[kind])
    for robot in data["robots"].values():
        robot["urdf"] = str(examples_dir / robot["urdf"])
        robot["package_paths"] = {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")}
    data["output"].update(output)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_the_option_reaches_each_segments_recording_but_not_the_model(examples_dir: Path, tmp_path: Path) -> None:
    split = compile_config(_example(examples_dir, tmp_path, "so101_dataset.yaml", {"joint_series": True, "episodes": "0:2"}))
    assert split.dataset.joint_series
    assert all(split.for_segment(segment).output.joint_series for segment in split.segments)
    assert not split.for_model().output.joint_series  # the model asset holds no values
    plain = compile_config(_example(examples_dir, tmp_path, "demo.yaml", {}))
    assert not plain.dataset.joint_series and not plain.for_segment(plain.segments[0]).output.joint_series


def test_the_option_changes_the_segments_content_hash_and_not_the_models(examples_dir: Path, tmp_path: Path) -> None:
    plan = compile_config(_example(examples_dir, tmp_path, "so101_dataset.yaml", {"episodes": "0:2"}))
    with_series = replace(plan, dataset=replace(plan.dataset, joint_series=True))
    for with_model in (True, False):
        before, after = segment_hashes(plan, with_model), segment_hashes(with_series, with_model)
        assert before.keys() == after.keys() and all(before[key] != after[key] for key in before)
    assert model_hash(plan) == model_hash(with_series)


def test_a_config_whose_robots_no_source_drives_is_warned(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    (tmp_path / "scene.urdf").write_text(SCENE)
    write_joint_parquet(tmp_path / "base.parquet", np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], (3, 1)), column="pose")
    config = {
        "version": 1,
        "sources": {
            "base": {"parquet": "base.parquet", "column": "pose", "index": "frame_index", "names": ["x", "y", "z", "qx", "qy", "qz", "qw"]}
        },
        "robots": {"scene": {"urdf": "scene.urdf"}},
        "frames": {"root": "world"},
        "edges": [
            {
                "parent": "world",
                "child": "table",
                "source": "base",
                "translation": ["x", "y", "z"],
                "quaternion_xyzw": ["qx", "qy", "qz", "qw"],
            }
        ],
        "output": {"path": "out/{segment}.rrd", "application_id": "scene", "segment": "scene", "joint_series": True},
    }
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    result = run_cli("validate", str(path))
    assert result.code == 0, result.err
    assert "output.joint_series: no robot of this config is driven by a source: joint_series plots nothing" in result.err
    del config["output"]["joint_series"]  # type: ignore[attr-defined]
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    assert "joint_series" not in run_cli("validate", str(path)).err

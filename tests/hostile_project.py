"""A small project for tests that build hostile inputs: a one-joint robot with a mesh, a parquet source and its
config as data (each test changes what it needs, then writes it), all in a folder of the test's own."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from urdf_pipeline.examples import write_joint_parquet

URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base_link"/>
  <link name="link1"><visual><geometry><mesh filename="package://arm/meshes/{mesh}"/></geometry></visual></link>
  <joint name="joint1" type="revolute"><parent link="base_link"/><child link="link1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""
ONE_TRIANGLE = b"\0" * 80 + struct.pack("<I", 1) + struct.pack("<12f", 0, 0, 1, 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0) + b"\0\0"


def make_project(root: Path, mesh: str = "link1.stl") -> dict[str, Any]:
    """A one-joint robot with a mesh, a parquet source and its config (returned as data, written by `write_config`)."""
    (root / "robots" / "arm" / "urdf").mkdir(parents=True)
    (root / "robots" / "arm" / "meshes").mkdir()
    (root / "robots" / "arm" / "meshes" / "link1.stl").write_bytes(ONE_TRIANGLE)
    (root / "robots" / "arm" / "urdf" / "arm.urdf").write_text(URDF.format(mesh=mesh), encoding="utf-8")
    write_joint_parquet(root / "data" / "episode_000.parquet", np.linspace(-1, 1, 50)[:, None])
    return {
        "version": 1,
        "sources": {
            "state": {"parquet": "data/episode_000.parquet", "column": "observation.state", "index": "frame_index", "names": ["j1"]}
        },
        "robots": {
            "arm": {
                "urdf": "robots/arm/urdf/arm.urdf",
                "package_paths": {"arm": "robots/arm"},
                "joints": {"source": "state", "unit": "rad", "map": {"j1": "joint1"}},
            }
        },
        "output": {"path": "out/{segment}.rrd", "application_id": "os_test", "segment": "episode_000"},
    }


def write_config(root: Path, data: dict[str, Any], name: str = "config.yaml") -> Path:
    path = root / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def loop(path: Path) -> str:
    """`path` and a sibling made into symlinks to each other (again, when a module fixture runs twice); returns
    `path`'s name."""
    other = path.with_name(path.name + ".other")
    for link in (path, other):
        if link.is_symlink():
            link.unlink()
    path.symlink_to(other.name)
    other.symlink_to(path.name)
    return path.name


def set_key(data: dict[str, Any], dotted: str, value: Any) -> None:
    """`data` with the entry at the dotted YAML path set (`robots.arm.urdf`)."""
    *parents, last = dotted.split(".")
    for part in parents:
        data = data[part]
    data[last] = value

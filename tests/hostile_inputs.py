"""Inputs of the os_*, hdf5_unwritten_rows, hdf5_external_link and index_* cases in tests/configs/invalid/ (made by
test_invalid_configs.py's fixture): symlink loops, a file in the way of an output folder, a file name with a newline,
an HDF5 file declaring 2^34 unwritten rows or linking to another file, index values beyond a timeline."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from urdf_pipeline.examples import write_joint_parquet

from .hostile_project import loop


def write_hostile_inputs(directory: Path, raw: np.ndarray) -> None:
    """`directory`: the examples folder (robots/, data/, out/); `raw`: Panda values, one column per joint name."""
    robots, data = directory / "robots", directory / "data"
    loop(robots / "os_loop.urdf")
    (data / "os_glob").mkdir(exist_ok=True)
    write_joint_parquet(data / "os_glob" / "ep0.parquet", raw)
    loop(data / "os_glob" / "loop.parquet")
    (data / "os_control").mkdir(exist_ok=True)
    write_joint_parquet(data / "os_control" / "ep0.parquet", raw)
    shutil.copyfile(data / "os_control" / "ep0.parquet", data / "os_control" / "ep\n::error::forged.parquet")
    (directory / "out" / "invalid").mkdir(parents=True, exist_ok=True)
    (directory / "out" / "invalid" / "os_blocker").write_text("a file where output.path needs a folder\n", encoding="utf-8")

    with h5py.File(data / "hdf5_unwritten.h5", "w") as file:  # 2432 bytes on disk
        file.create_dataset("observations/qpos", shape=(2**34, raw.shape[1]), chunks=(1024, raw.shape[1]), dtype="f4")
    with h5py.File(data / "hdf5_linked_target.h5", "w") as file:
        file["values"] = raw
    with h5py.File(data / "hdf5_external_link.h5", "w") as file:
        file["observations/qpos"] = h5py.ExternalLink("hdf5_linked_target.h5", "/values")

    write_joint_parquet(data / "index_uint64.parquet", raw)
    table = pq.read_table(data / "index_uint64.parquet")
    frames = np.arange(len(raw), dtype=np.uint64)
    frames[150] = 2**63
    pq.write_table(
        table.set_column(table.schema.get_field_index("frame_index"), "frame_index", pa.array(frames)), data / "index_uint64.parquet"
    )
    write_joint_parquet(data / "index_seconds_1e12.parquet", raw)
    table = pq.read_table(data / "index_seconds_1e12.parquet")
    seconds = np.arange(len(raw)) / 30.0
    seconds[120] = 1e12
    pq.write_table(
        table.set_column(table.schema.get_field_index("timestamp"), "timestamp", pa.array(seconds)), data / "index_seconds_1e12.parquet"
    )

"""Corrupt, empty or odd data files are user errors: exit 1, one line naming the file, nothing written, never a hang."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from .test_sources_mcap import JOINT_STATE_MSGDEF


def corrupt_parquet(path: Path, column: str) -> None:
    """Rewrite with page checksums, then zero 64 bytes in the middle of `column`'s chunk: the footer stays valid."""
    pq.write_table(pq.read_table(path), path, compression="snappy", write_page_checksum=True)
    meta = pq.ParquetFile(path).metadata
    data = bytearray(path.read_bytes())
    for group in range(meta.num_row_groups):
        for i in range(meta.num_columns):
            chunk = meta.row_group(group).column(i)
            if chunk.path_in_schema.split(".list.")[0] == column:
                middle = (chunk.dictionary_page_offset or chunk.data_page_offset) + chunk.total_compressed_size // 2
                data[middle : middle + 64] = bytes(64)
    path.write_bytes(bytes(data))


def config_from(examples_dir: Path, example: str, name: str, old: str, new: str) -> Path:
    text = (examples_dir / example).read_text(encoding="utf-8")
    assert old in text
    segment = next(line for line in text.splitlines() if line.strip().startswith("segment:"))
    text = text.replace(old, new).replace(segment, f"  segment: {name}")
    config = examples_dir / f"bad_data_{name}.yaml"
    config.write_text(text, encoding="utf-8")
    return config


def assert_refused(result, *expected: str) -> None:
    assert result.code == 1, f"exit {result.code}\n{result.err}"
    assert "Traceback" not in result.err and "internal error" not in result.err, result.err
    errors = [line for line in result.err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.err
    for text in expected:
        assert text in errors[0], errors[0]
    assert not result.out.strip()


def test_parquet_with_corrupt_data_pages(examples_dir: Path, run_cli) -> None:
    bad = examples_dir / "data" / "bad_pages.parquet"
    shutil.copyfile(examples_dir / "data" / "episode_000.parquet", bad)
    corrupt_parquet(bad, "observation.state")
    config = config_from(examples_dir, "demo.yaml", "bad_pages", "data/episode_000.parquet", "data/bad_pages.parquet")
    for command in ("validate", "run"):
        assert_refused(run_cli(command, str(config)), str(bad), "row group 0 of 1", "corrupt")
    assert not list((examples_dir / "out").glob("bad_pages*"))


def test_lerobot_episode_with_corrupt_data_file(examples_dir: Path, run_cli) -> None:
    root = examples_dir / "data" / "so101_corrupt"
    shutil.copytree(examples_dir / "data" / "so101_lerobot", root, dirs_exist_ok=True)
    episode = root / "data" / "chunk-000" / "episode_000000.parquet"
    corrupt_parquet(episode, "observation.state")
    config = config_from(examples_dir, "so101_lerobot.yaml", "lerobot_corrupt", "data/so101_lerobot", "data/so101_corrupt")
    for command in ("validate", "run"):
        assert_refused(run_cli(command, str(config)), "episode 0", str(episode), "row group 0")


def test_lerobot_episode_with_zero_frames(examples_dir: Path, run_cli) -> None:
    root = examples_dir / "data" / "so101_empty_episode"
    shutil.copytree(examples_dir / "data" / "so101_lerobot", root, dirs_exist_ok=True)
    episodes = root / "meta" / "episodes.jsonl"
    episodes.write_text(episodes.read_text(encoding="utf-8").replace('"length": 300', '"length": 0'), encoding="utf-8")
    config = config_from(examples_dir, "so101_lerobot.yaml", "lerobot_empty", "data/so101_lerobot", "data/so101_empty_episode")
    assert_refused(run_cli("validate", str(config)), "episode 0", str(root), "zero frames")


def _aloha_config(examples_dir: Path, name: str, file: Path) -> Path:
    return config_from(examples_dir, "aloha_bimanual.yaml", name, "data/aloha/episode_*.hdf5", f"data/{file.name}")


def test_hdf5_with_corrupt_chunk(examples_dir: Path, run_cli) -> None:
    with h5py.File(examples_dir / "data" / "aloha" / "episode_0.hdf5") as file:
        qpos = file["/observations/qpos"][()]
    bad = examples_dir / "data" / "aloha_corrupt_chunk.hdf5"
    with h5py.File(bad, "w") as file:
        file.create_dataset("/observations/qpos", data=qpos, chunks=(50, qpos.shape[1]), compression="gzip")
    with h5py.File(bad) as file:
        info = file["/observations/qpos"].id.get_chunk_info(1)
    data = bytearray(bad.read_bytes())
    data[info.byte_offset + 10 : info.byte_offset + 40] = np.random.default_rng(3).bytes(30)
    bad.write_bytes(bytes(data))
    config = _aloha_config(examples_dir, "hdf5_corrupt_chunk", bad)
    for command in ("validate", "run"):
        assert_refused(run_cli(command, str(config)), str(bad), "'/observations/qpos'", "corrupt")


def test_truncated_hdf5(examples_dir: Path, run_cli) -> None:
    bad = examples_dir / "data" / "aloha_truncated.hdf5"
    whole = (examples_dir / "data" / "aloha" / "episode_0.hdf5").read_bytes()
    bad.write_bytes(whole[: len(whole) // 3])
    config = _aloha_config(examples_dir, "hdf5_truncated", bad)
    for command in ("validate", "run"):
        assert_refused(run_cli(command, str(config)), str(bad), "truncated")


def test_hdf5_dataset_with_zero_rows(examples_dir: Path, run_cli) -> None:
    empty = examples_dir / "data" / "aloha_empty.hdf5"
    with h5py.File(empty, "w") as file:
        file.create_dataset("/observations/qpos", data=np.zeros((0, 14)))
    assert_refused(run_cli("validate", str(_aloha_config(examples_dir, "hdf5_empty", empty))), str(empty), "zero rows")


def test_empty_parquet_reported_by_validate_from_its_footer(examples_dir: Path, run_cli) -> None:
    empty = examples_dir / "data" / "no_rows.parquet"
    pq.write_table(pq.read_table(examples_dir / "data" / "episode_000.parquet").slice(0, 0), empty)
    config = config_from(examples_dir, "demo.yaml", "no_rows", "data/episode_000.parquet", "data/no_rows.parquet")
    assert_refused(run_cli("validate", str(config)), str(empty), "zero rows", "footer")


def test_corrupt_rrd(examples_dir: Path, run_cli) -> None:
    from ..source_helpers import panda_config
    from .test_sources_rrd import write_state_rrd

    good = examples_dir / "data" / "state_for_corruption.rrd"
    write_state_rrd(good, np.zeros((200, 8)), None)
    data = bytearray(good.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 200] = bytes(200)
    bad = examples_dir / "data" / "state_corrupt.rrd"
    bad.write_bytes(bytes(data))
    names = [f"v{i}" for i in range(8)]
    config = panda_config(examples_dir, "rrd_corrupt", {"rrd": "data/state_corrupt.rrd", "entity": "/observation.state", "names": names},
                          dict(zip(names, ["panda_joint1", "panda_joint2", "panda_joint3", "panda_joint4", "panda_joint5", "panda_joint6", "panda_joint7", {"joint": "panda_finger_joint1", "unit": "m"}], strict=True)))  # fmt: skip
    for command in ("validate", "run"):
        assert_refused(run_cli(command, str(config)), str(bad), "corrupt")


# --- MCAP: run in a subprocess, so a hang fails the test instead of stalling the suite --------------------------


def _mcap_variants(good: bytes) -> dict[str, bytes]:
    rng = np.random.default_rng(11)
    flipped = bytearray(good)
    for i in range(400, len(good) - 400, 97):  # inside the one compressed chunk
        flipped[i] ^= 0xFF
    return {"truncated": good[: len(good) // 2], "flipped": bytes(flipped), "garbage": good[:8] + rng.bytes(5000)}


def _probes_left(path: Path) -> list[str]:
    left = []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cmdline = (proc / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if str(path) in cmdline and "mcap_probe" in cmdline:
            left.append(proc.name)
    return left


@pytest.mark.parametrize("variant", ["truncated", "flipped", "garbage"])
@pytest.mark.parametrize("command", ["validate", "run"])
def test_corrupt_mcap_is_refused_without_hanging(examples_dir: Path, variant: str, command: str) -> None:
    good = examples_dir / "data" / "ur5_joint_states.mcap"
    bad = examples_dir / "data" / f"ur5_{variant}.mcap"
    bad.write_bytes(_mcap_variants(good.read_bytes())[variant])
    config = config_from(examples_dir, "ur5_ros2_bag.yaml", f"mcap_{variant}_{command}", "data/ur5_joint_states.mcap", f"data/{bad.name}")
    args = [sys.executable, "-m", "urdf_pipeline", command, str(config)] + (["--jobs", "1"] if command == "run" else [])
    result = subprocess.run(args, capture_output=True, text=True, timeout=60, env={**os.environ, "NO_COLOR": "1"})
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert result.returncode == 1, result.stderr
    assert len(errors) == 1 and str(bad) in errors[0], result.stderr
    assert "Traceback" not in result.stderr
    assert not _probes_left(bad)
    assert not list((examples_dir / "out").glob(f"mcap_{variant}_{command}*"))


def test_mcap_topic_without_messages(examples_dir: Path, run_cli) -> None:
    from mcap.writer import Writer

    bad = examples_dir / "data" / "ur5_no_messages.mcap"
    with bad.open("wb") as stream:  # a JointState channel that carries no message
        writer = Writer(stream)
        writer.start(profile="ros2")
        schema = writer.register_schema("sensor_msgs/msg/JointState", "ros2msg", JOINT_STATE_MSGDEF.encode())
        writer.register_channel("/joint_states", "cdr", schema)
        writer.finish()
    config = config_from(examples_dir, "ur5_ros2_bag.yaml", "mcap_no_messages", "data/ur5_joint_states.mcap", f"data/{bad.name}")
    assert_refused(run_cli("validate", str(config)), str(bad), "no messages")


# --- Index values: duplicates and order ----------------------------------------------------------------------------


def _with_frame_index(examples_dir: Path, name: str, frame_index: np.ndarray) -> Path:
    """The example's rows (repeated to fill `frame_index`) with this frame_index column."""
    one = pq.read_table(examples_dir / "data" / "episode_000.parquet")
    table = pa.concat_tables([one] * -(-len(frame_index) // one.num_rows)).slice(0, len(frame_index))
    table = table.set_column(table.schema.get_field_index("frame_index"), "frame_index", pa.array(frame_index))
    pq.write_table(table, examples_dir / "data" / f"{name}.parquet")
    return config_from(examples_dir, "demo.yaml", name, "data/episode_000.parquet", f"data/{name}.parquet")


def test_duplicate_index_values_name_the_first(examples_dir: Path, run_cli) -> None:
    frame_index = np.arange(300)
    frame_index[120] = 119
    frame_index[200] = 199
    config = _with_frame_index(examples_dir, "duplicate_frames", frame_index)
    result = run_cli("run", str(config))
    assert_refused(result, "duplicate_frames.parquet", "2 rows", "frame_index = 119 at rows 119, 120", "duplicates: keep_last")
    assert not (examples_dir / "out" / "duplicate_frames.rrd").exists()


def test_duplicates_keep_last(examples_dir: Path, run_cli) -> None:
    frame_index = np.arange(300)
    frame_index[120] = 119
    config = _with_frame_index(examples_dir, "duplicate_frames_kept", frame_index)
    text = config.read_text(encoding="utf-8").replace("    names: [", "    duplicates: keep_last\n    names: [", 1)
    assert "duplicates: keep_last" in text
    config.write_text(text, encoding="utf-8")
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert "kept the last of each (duplicates: keep_last)" in result.err


def test_rows_out_of_order_are_sorted_with_a_note(examples_dir: Path, run_cli) -> None:
    # Two halves swapped, 3000 rows: Rerun's parquet reader sorts each 1024-row chunk by itself; across chunks we sort
    frame_index = np.r_[1500:3000, 0:1500]
    config = _with_frame_index(examples_dir, "frames_out_of_order", frame_index)
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    notes = [line for line in result.err.splitlines() if line.startswith("note:") and "out of frame_index order" in line]
    assert len(notes) == 1, result.err
    assert "frames_out_of_order.parquet" in notes[0] and "sorted by frame_index, stably" in notes[0]

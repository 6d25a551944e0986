"""Data files built to stall or to deceive: an HDF5 file of a few KB that declares 2^34 rows, datasets whose values
live in other files, and index values a timeline cannot hold (uint64 at or above 2^63, times whose nanoseconds
overflow int64). Each is refused by `validate` (metadata and the index column only, bounded by the bytes stored) and
by `run`, naming the dataset or column and, for index values, the row; nothing is written."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from urdf_pipeline.examples import write_lerobot_dataset

from ..hostile_project import make_project, set_key, write_config

ROWS = 50
VALUES = np.linspace(-1, 1, ROWS)


def _refused(run_cli, config: Path, *expected: str, commands: tuple[str, ...] = ("validate", "plan", "run")) -> None:
    for command in commands:
        result = run_cli(command, str(config))
        assert result.code == 1, f"{command}: exit {result.code}\n{result.err}"
        assert "Traceback" not in result.err and "internal error" not in result.err, result.err
        errors = [line for line in result.err.splitlines() if line.startswith("error")]
        assert len(errors) == 1 and errors[0].startswith(f"error: {config}:"), result.err
        for text in expected:
            assert text in errors[0], errors[0]
    out = config.parent / "out"
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())  # a data-stage refusal may leave the folder only


def _hdf5_config(root: Path, write: Callable[[h5py.File], None], index: Any = None) -> Path:
    data = make_project(root)
    with h5py.File(root / "data" / "episode.h5", "w") as file:
        write(file)
    source: dict[str, Any] = {"hdf5": "data/episode.h5", "dataset": "/qpos", "names": ["j1"]}
    if index is not None:
        source["index"] = index
    set_key(data, "sources.state", source)
    return write_config(root, data)


# HDF5: declared shape against bytes stored


def test_hdf5_of_unwritten_chunks_is_refused_fast(tmp_path: Path, run_cli) -> None:
    """2^34 rows declared, no chunk written: a few KB on disk. Before, validate read 2^34 fill values (minutes) and
    run grew past 24 GB; now the declared size is compared with the chunks stored, from metadata only."""
    config = _hdf5_config(tmp_path, lambda f: f.create_dataset("qpos", shape=(2**34, 1), chunks=(1024, 1), dtype="f4"))
    assert (tmp_path / "data" / "episode.h5").stat().st_size < 10_000
    _refused(
        run_cli, config, "sources.state.dataset:", "'/qpos'", "declares 17179869184 rows", "stores 0 bytes", "0 of its 16777216 chunks"
    )


def test_hdf5_resized_beyond_what_was_written_is_refused(tmp_path: Path, run_cli) -> None:
    """maxshape and a resize: 100 rows written, 2^30 declared (the rest would read as the fill value)."""

    def write(file: h5py.File) -> None:
        dataset = file.create_dataset("qpos", data=np.ones((100, 1)), maxshape=(None, 1), chunks=(64, 1), fillvalue=0.5)
        dataset.resize((2**30, 1))

    _refused(run_cli, _hdf5_config(tmp_path, write), "declares 1073741824 rows", "2 of its 16777216 chunks were written")


def test_hdf5_partly_written_chunks_are_refused(tmp_path: Path, run_cli) -> None:
    """A log preallocated for 10,000 rows, stopped after 100: zeros would be drawn as joint values."""

    def write(file: h5py.File) -> None:
        file.create_dataset("qpos", shape=(10_000, 1), chunks=(100, 1), dtype="f8")[:100] = 1.0

    _refused(run_cli, _hdf5_config(tmp_path, write), "declares 10000 rows", "1 of its 100 chunks were written")


def test_hdf5_contiguous_never_written_is_refused(tmp_path: Path, run_cli) -> None:
    config = _hdf5_config(tmp_path, lambda f: f.create_dataset("qpos", shape=(2**34, 1), dtype="f4"))
    _refused(run_cli, config, "declares 17179869184 rows", "stores 0 bytes")


@pytest.mark.parametrize(
    "filters", [{"scaleoffset": 2, "compression": "gzip"}, {"compression": "gzip", "compression_opts": 9}], ids=["scaleoffset", "gzip"]
)
def test_hdf5_compressed_beyond_any_joint_data_is_refused(filters: dict[str, Any], tmp_path: Path, run_cli) -> None:
    """Compression bombs: 2^26 zero rows (256 MB), every chunk written, in 14 KB (scale-offset, then gzip: no bound)
    or 260 KB (gzip alone: ~1032:1). Before, run streamed every row of a 2 MB file of this kind for minutes."""

    def write(file: h5py.File) -> None:
        dataset = file.create_dataset("qpos", shape=(2**26, 1), chunks=(2**20, 1), dtype="f4", **filters)
        block = np.zeros((2**20, 1), np.float32)
        for start in range(0, 2**26, 2**20):  # every chunk written: only the ratio gives it away
            dataset[start : start + 2**20] = block

    _refused(run_cli, _hdf5_config(tmp_path, write), "declares 67108864 rows", "more than 100 times less than declared")


def test_a_small_constant_hdf5_dataset_passes(tmp_path: Path, run_cli) -> None:
    """An idle recording: a constant signal packs ~1000:1, let through below 64 MB declared."""

    def write(file: h5py.File) -> None:
        file.create_dataset("qpos", data=np.zeros((2**20, 1)), chunks=(2**16, 1), compression="gzip", compression_opts=9)

    result = run_cli("validate", str(_hdf5_config(tmp_path, write)))
    assert result.code == 0, result.err


def test_hdf5_compressed_joint_values_pass(tmp_path: Path, run_cli) -> None:
    """The control: real values, gzip and shuffle, chunked and contiguous layouts, compact too."""
    for name, options in {
        "gzip": {"chunks": (16, 1), "compression": "gzip", "shuffle": True},
        "contiguous": {},
        "compact": {"compact": True},
    }.items():
        root = tmp_path / name
        root.mkdir()

        def write(file: h5py.File, options: dict[str, Any] = options) -> None:
            if options.pop("compact", False):
                space = h5py.h5s.create_simple((ROWS, 1))
                plist = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
                plist.set_layout(h5py.h5d.COMPACT)
                h5py.h5d.create(file.id, b"qpos", h5py.h5t.IEEE_F64LE, space, plist).write(
                    h5py.h5s.ALL, h5py.h5s.ALL, VALUES[:, None].copy()
                )
            else:
                file.create_dataset("qpos", data=VALUES[:, None], **options)
            file.create_dataset("t", data=np.arange(ROWS) / 30.0)

        config = _hdf5_config(root, write, {"timestamp": "/t", "unit": "s"})
        for command in ("validate", "run"):
            result = run_cli(command, str(config))
            assert result.code == 0, (name, command, result.err)


def test_hdf5_external_storage_is_refused(tmp_path: Path, run_cli) -> None:
    """External raw storage reads another file, whatever the read rule says: refused before it is opened."""
    (tmp_path / "raw.bin").write_bytes(VALUES.astype("<f8").tobytes())

    def write(file: h5py.File) -> None:
        file.create_dataset("qpos", shape=(ROWS, 1), dtype="<f8", external=[(str(tmp_path / "raw.bin"), 0, ROWS * 8)])

    _refused(run_cli, _hdf5_config(tmp_path, write), "'/qpos'", "keeps its values in external raw files")


def test_hdf5_virtual_dataset_is_refused(tmp_path: Path, run_cli) -> None:
    with h5py.File(tmp_path / "other.h5", "w") as other:
        other["values"] = VALUES[:, None]

    def write(file: h5py.File) -> None:
        layout = h5py.VirtualLayout(shape=(ROWS, 1), dtype="f8")
        layout[:] = h5py.VirtualSource(str(tmp_path / "other.h5"), "values", shape=(ROWS, 1))
        file.create_virtual_dataset("qpos", layout)

    _refused(run_cli, _hdf5_config(tmp_path, write), "'/qpos'", "is a virtual dataset")


def test_hdf5_external_link_is_refused(tmp_path: Path, run_cli) -> None:
    """An external link (here at the dataset's own path) would make h5py and Rerun open another file."""
    with h5py.File(tmp_path / "other.h5", "w") as other:
        other["values"] = VALUES[:, None]

    def write(file: h5py.File) -> None:
        file["qpos"] = h5py.ExternalLink(str(tmp_path / "other.h5"), "/values")

    _refused(run_cli, _hdf5_config(tmp_path, write), "sources.state.hdf5:", "holds an external link (/qpos)")


def test_hdf5_soft_link_loop_is_refused(tmp_path: Path, run_cli) -> None:
    def write(file: h5py.File) -> None:
        file["qpos"] = h5py.SoftLink("/loop")
        file["loop"] = h5py.SoftLink("/qpos")

    result = run_cli("validate", str(_hdf5_config(tmp_path, write)))
    assert result.code == 1 and "Traceback" not in result.err, result.err
    assert "sources.state.dataset:" in result.err


# Index values a timeline cannot hold


def _parquet_config(root: Path, index_values: pa.Array, index: Any, wide: bool = False) -> Path:
    data = make_project(root)
    if wide:
        table = pa.table({"t": index_values, "j1": pa.array(VALUES)})
        source: dict[str, Any] = {"parquet": "data/episode.parquet", "index": index}
    else:
        table = pa.table({"t": index_values, "v": pa.FixedSizeListArray.from_arrays(pa.array(VALUES), 1)})
        source = {"parquet": "data/episode.parquet", "column": "v", "index": index, "names": ["j1"]}
    pq.write_table(table, root / "data" / "episode.parquet")
    set_key(data, "sources.state", source)
    return write_config(root, data)


def _with(values: np.ndarray, at: int, value: Any) -> np.ndarray:
    values = values.copy()
    values[at] = value
    return values


SECONDS = np.arange(ROWS) / 30.0
STEPS = np.arange(ROWS, dtype=np.uint64)
MILLIS = np.arange(ROWS, dtype=np.int64) * 33
PARQUET_CASES = {
    "uint64_at_2_63": (pa.array(_with(STEPS, 40, 2**63)), "t", "holds 9223372036854775808 at row 40"),
    "float_seconds_1e12": (pa.array(_with(SECONDS, 10, 1e12)), {"timestamp": "t", "unit": "s"}, "at row 10", "say unit: ms"),
    "float_seconds_inf": (pa.array(_with(SECONDS, 11, np.inf)), {"timestamp": "t", "unit": "s"}, "holds inf s at row 11", "finite"),
    "float_seconds_nan": (pa.array(_with(SECONDS, 12, np.nan)), {"duration": "t", "unit": "s"}, "holds nan s at row 12"),
    "millis_2_62": (
        pa.array(_with(MILLIS, 20, 2**62)),
        {"duration": "t", "unit": "ms"},
        "holds 4611686018427387904 ms at row 20",
        "unit: ns",
    ),
    "int64_min": (pa.array(_with(MILLIS, 21, -(2**63))), "t", "at row 21"),
    "timestamp_seconds_type": (
        pa.array(_with(MILLIS, 22, 2**40)).cast(pa.timestamp("s")),
        {"timestamp": "t", "unit": "s"},
        "holds 1099511627776000 ms at row 22",  # parquet keeps seconds as milliseconds: the type's own unit counts
    ),
}


@pytest.mark.parametrize("wide", [False, True], ids=["list_column", "wide_table"])
@pytest.mark.parametrize("case", sorted(PARQUET_CASES))
def test_parquet_index_beyond_a_timeline_is_refused(case: str, wide: bool, tmp_path: Path, run_cli) -> None:
    values, index, *expected = PARQUET_CASES[case]
    config = _parquet_config(tmp_path, values, index, wide)
    _refused(run_cli, config, "sources.state.index:", "index column 't' of", *expected)


def test_index_at_the_edge_of_the_range_passes(tmp_path: Path, run_cli) -> None:
    """The control: the largest times that fit are kept (9.2e9 s, 2^63 - 1 steps)."""
    for name, values, index in [
        ("steps", _with(STEPS, ROWS - 1, 2**63 - 1), "t"),
        ("seconds", _with(SECONDS, ROWS - 1, 9.2e9), {"timestamp": "t", "unit": "s"}),
    ]:
        root = tmp_path / name
        root.mkdir()
        result = run_cli("validate", str(_parquet_config(root, pa.array(values), index)))
        assert result.code == 0, (name, result.err)


def test_csv_index_beyond_a_timeline_is_refused(tmp_path: Path, run_cli) -> None:
    """validate reads the first block; run checks every block as it reads it."""
    data = make_project(tmp_path)
    rows = "".join(f"{1e12 if i == 5 else i / 30},{v}\n" for i, v in enumerate(VALUES))
    (tmp_path / "data" / "episode.csv").write_text("t,j1\n" + rows, encoding="utf-8")
    set_key(data, "sources.state", {"csv": "data/episode.csv", "index": {"timestamp": "t", "unit": "s"}})
    _refused(run_cli, write_config(tmp_path, data), "sources.state.index:", "index column 't' of", "at row 5")


def test_csv_index_beyond_a_timeline_after_the_first_block_is_refused_by_run(tmp_path: Path, run_cli) -> None:
    data = make_project(tmp_path)
    many = 200_000  # beyond the 1 MiB first block validate reads
    times = np.arange(many) / 30.0
    times[many - 3] = np.inf
    lines = "\n".join(f"{t},0.0" for t in times)
    (tmp_path / "data" / "episode.csv").write_text("t,j1\n" + lines + "\n", encoding="utf-8")
    set_key(data, "sources.state", {"csv": "data/episode.csv", "index": {"timestamp": "t", "unit": "s"}})
    config = write_config(tmp_path, data)
    assert run_cli("validate", str(config)).code == 0
    _refused(run_cli, config, f"holds inf s at row {many - 3}", commands=("run",))


def test_hdf5_index_beyond_a_timeline_is_refused(tmp_path: Path, run_cli) -> None:
    def write(file: h5py.File) -> None:
        file["qpos"] = VALUES[:, None]
        file["t"] = _with(SECONDS, 3, 1e12)
        file["steps"] = _with(STEPS, 4, 2**63 + 1)

    config = _hdf5_config(tmp_path, write, {"timestamp": "/t", "unit": "s"})
    _refused(run_cli, config, "sources.state.index:", "index dataset '/t'", "at row 3")
    set_key(data := __import__("yaml").safe_load(config.read_text()), "sources.state.index", "/steps")
    config = write_config(tmp_path, data)
    _refused(run_cli, config, "index dataset '/steps'", "holds 9223372036854775809 at row 4")


def test_lerobot_frame_index_beyond_a_timeline_is_refused(tmp_path: Path, run_cli) -> None:
    data = make_project(tmp_path)
    root = tmp_path / "data" / "dataset"
    write_lerobot_dataset(root, VALUES[:, None], ["j1"])
    episode = root / "data" / "chunk-000" / "episode_000000.parquet"
    table = pq.read_table(episode)
    frames = _with(np.arange(ROWS, dtype=np.uint64), 30, 2**63 + 7)
    table = table.set_column(table.schema.get_field_index("frame_index"), "frame_index", pa.array(frames))
    pq.write_table(table, episode)
    set_key(data, "sources.state", {"lerobot": "data/dataset", "episode": 0})
    _refused(run_cli, write_config(tmp_path, data), "frame_index", "holds 9223372036854775815 at row 30")


def test_mcap_log_times_beyond_a_timeline_are_refused(tmp_path: Path, run_cli) -> None:
    """MCAP log and publish times are uint64 ns; Rerun clamps those at or beyond 2^63 to 2262-04-11 (seen: the
    last message's 2^63 + 5 became 2^63 - 1), which would stack the late messages at one time."""
    from .test_sources_mcap import write_joint_states

    data = make_project(tmp_path)
    path = tmp_path / "data" / "joint_states.mcap"
    write_joint_states(path, [(["j1"], [float(v)]) for v in VALUES])
    _rewrite_log_times(path, 2**63 + 5)
    set_key(data, "sources.state", {"mcap": "data/joint_states.mcap", "topic": "/joint_states", "timeline": "log_time"})
    config = write_config(tmp_path, data)
    _refused(run_cli, config, "sources.state.timeline:", "logged at up to 9223372036854775813 ns", f"at row {ROWS - 1}")
    set_key(data, "sources.state.timeline", "publish_time")
    _refused(run_cli, write_config(tmp_path, data), "message_publish_time at or beyond 2^63 ns", commands=("run",))


def _rewrite_log_times(path: Path, last: int) -> None:
    """The file again, its last /joint_states message logged and published at `last` ns."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with path.open("rb") as stream:
        reader = make_reader(stream)
        records = list(reader.iter_messages())
    out = path.with_suffix(".tmp")
    with out.open("wb") as stream:
        writer = Writer(stream)
        writer.start()
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, _ in records:
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(channel.topic, channel.message_encoding, schemas[schema.id])
        final = max(i for i, (_, channel, _) in enumerate(records) if channel.topic == "/joint_states")
        for i, (_, channel, message) in enumerate(records):
            time = last if i == final else message.log_time
            writer.add_message(channels[channel.id], time, message.data, time, message.sequence)
        writer.finish()
    out.replace(path)


# LeRobot metadata from a stranger: every file it names is checked before pyarrow or Rerun opens it


def _lerobot_config(root: Path) -> tuple[Path, Path]:
    data = make_project(root)
    dataset = root / "data" / "dataset"
    write_lerobot_dataset(dataset, [VALUES[:, None], VALUES[:, None]], ["j1"])
    set_key(data, "sources.state", {"lerobot": "data/dataset"})
    set_key(data, "output.segment", "episode_{episode:06d}")
    return write_config(root, data), dataset


def _edit_info(dataset: Path, **changes: Any) -> None:
    import json

    path = dataset / "meta" / "info.json"
    path.write_text(json.dumps({**json.loads(path.read_text(encoding="utf-8")), **changes}), encoding="utf-8")


LEROBOT_CASES: dict[str, tuple[Callable[[Path], None], str]] = {
    "episodes_jsonl_not_json": (
        lambda d: (d / "meta" / "episodes.jsonl").write_text("{broken\n", encoding="utf-8"),
        "cannot read the episode metadata of LeRobot dataset",
    ),
    "info_json_a_list": (lambda d: (d / "meta" / "info.json").write_text("[1, 2]", encoding="utf-8"), "holds list, not a JSON object"),
    "data_path_leaves_the_dataset": (
        lambda d: _edit_info(d, data_path="../../../elsewhere/{episode_index}.parquet"),
        "must stay inside the dataset",
    ),
    "data_path_reaches_into_python": (
        lambda d: _edit_info(d, data_path="data/{episode_index.__class__.__mro__}.parquet"),
        "reads an attribute or item",
    ),
    "data_file_a_fifo": (
        lambda d: _replace_with(d / "data" / "chunk-000" / "episode_000001.parquet", lambda p: __import__("os").mkfifo(p)),
        "is a FIFO",
    ),
    "data_file_linked_outside": (
        lambda d: _replace_with(
            d / "data" / "chunk-000" / "episode_000001.parquet", lambda p: p.symlink_to(d.parents[2] / "outside.parquet")
        ),
        "is outside the config's folder",
    ),
}


def _replace_with(path: Path, make: Callable[[Path], None]) -> None:
    (path.parents[5] / "outside.parquet").write_bytes(path.read_bytes())  # tmp_path, beside the project
    path.unlink()
    make(path)


@pytest.mark.parametrize("case", sorted(LEROBOT_CASES))
def test_hostile_lerobot_metadata_is_refused(case: str, tmp_path: Path, run_cli) -> None:
    project = tmp_path / "project"
    project.mkdir()
    config, dataset = _lerobot_config(project)
    assert run_cli("validate", str(config)).code == 0
    change, expected = LEROBOT_CASES[case]
    change(dataset)
    _refused(run_cli, config, "sources.state", expected)

"""Wide tables: a CSV (`csv: FILE`) or a parquet file without `column`, one numeric column per joint value named by
its header, plus an index column; read in bounded batches, checked against pinocchio end to end."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import timedelta
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

from urdf_pipeline.compile import compile_config
from urdf_pipeline.config.document import Document
from urdf_pipeline.errors import UserError
from urdf_pipeline.examples import PANDA_NAMES
from urdf_pipeline.plan import CsvSourcePlan, ParquetSourcePlan
from urdf_pipeline.sources import KINDS, EntryField, module_for
from urdf_pipeline.sources import csv as csv_kind
from urdf_pipeline.sources import parquet as parquet_kind
from urdf_pipeline.sources.ordering import BLOCK_ROWS
from urdf_pipeline.sources.wide import vector_chunks

from ..execute.test_fk_against_pinocchio import panda_contract_raw
from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, random_panda_q

# The contract's units (see panda_contract_raw): degrees, j2 negated, j3 offset by 0.1 rad, the finger in mm.
CONTRACT_MAP = {
    "j1": {"joint": "panda_joint1", "unit": "deg"},
    "j2": {"joint": "panda_joint2", "unit": "deg", "sign": -1},
    "j3": {"joint": "panda_joint3", "unit": "deg", "offset": 0.1},
    **{f"j{i}": {"joint": f"panda_joint{i}", "unit": "deg"} for i in range(4, 8)},
    "finger": {"joint": "panda_finger_joint1", "unit": "mm"},
}
EPOCH_S = 1_700_000_000.0
STEP_S = 1 / 64  # exact in binary: the expected nanoseconds are exact integers


def write_wide_csv(path: Path, columns: dict[str, np.ndarray], extra_lines: Sequence[str] = ()) -> None:
    """A plain CSV as loggers write it: a header line, then one line per row (full float precision)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    matrix = np.column_stack([np.asarray(v, dtype=np.float64) for v in columns.values()])
    formats = ["%d" if np.issubdtype(np.asarray(v).dtype, np.integer) else "%.17g" for v in columns.values()]
    with path.open("w", encoding="utf-8") as file:
        file.write(",".join(columns) + "\n")
        np.savetxt(file, matrix, delimiter=",", fmt=formats)
        file.writelines(line + "\n" for line in extra_lines)


def write_wide_parquet(path: Path, columns: dict[str, object], row_group_size: int | None = None) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table({name: pa.array(values) for name, values in columns.items()}), path, row_group_size=row_group_size)


def write_wide_inputs(data: Path, raw: np.ndarray) -> None:
    """Inputs of the csv_* and parquet_wide_* cases in tests/configs/invalid/ (`raw` in the contract's units)."""
    rows = len(raw)
    columns = {"time": np.arange(rows) / 30.0, **{name: raw[:, i] for i, name in enumerate(PANDA_NAMES)}}
    write_wide_csv(data / "wide_panda.csv", columns)
    header = ",".join(columns)
    lines = (data / "wide_panda.csv").read_text(encoding="utf-8").splitlines()
    (data / "wide_empty.csv").write_text("", encoding="utf-8")
    (data / "wide_header_only.csv").write_text(header + "\n", encoding="utf-8")
    (data / "wide_ragged.csv").write_text("\n".join([*lines[:40], "1.5,2.0,3.0", *lines[40:]]) + "\n", encoding="utf-8")
    (data / "wide_duplicate_header.csv").write_text("\n".join([header.replace("j7", "j6"), *lines[1:]]) + "\n", encoding="utf-8")
    noted = [f"{lines[0]},note", *(f"{line},calibrating" for line in lines[1:])]
    (data / "wide_text_column.csv").write_text("\n".join(noted) + "\n", encoding="utf-8")
    # Beyond the first block (validate reads only that one): 60 copies of the trajectory, a word in the last row.
    long = np.tile(raw, (60, 1))
    late = {"time": np.arange(len(long)) / 30.0, **{name: long[:, i] for i, name in enumerate(PANDA_NAMES)}}
    write_wide_csv(data / "wide_late_text.csv", late, extra_lines=[f"{len(long) / 30.0},1,2,3,-90,five,90,0,10"])
    assert (data / "wide_late_text.csv").stat().st_size > 2 * csv_kind.CSV_BLOCK_BYTES
    wide = {"frame": np.arange(rows), **{name: raw[:, i] for i, name in enumerate(PANDA_NAMES)}}
    write_wide_parquet(data / "wide_panda.parquet", wide)
    write_wide_parquet(data / "wide_text_column.parquet", {**wide, "operator": ["alice"] * rows})


def _expected_ns(times_s: np.ndarray) -> list[int]:
    return [int(v) for v in np.round(times_s * 1e9).astype(np.int64)]


def test_wide_csv_in_degrees_drives_the_panda_and_matches_pinocchio(examples_dir: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    """Degrees, a sign and an offset, the finger in mm, a timestamp index in seconds, columns in their own order and
    an extra integer column (ignored), read in many small blocks."""
    monkeypatch.setattr(csv_kind, "CSV_BLOCK_BYTES", 4096)  # about 20 rows a block: the file comes in many batches
    frames = 200
    q = random_panda_q(examples_dir, frames, seed=51)
    raw = panda_contract_raw(q)
    times = EPOCH_S + np.arange(frames) * STEP_S
    order = [7, 3, 0, 1, 2, 6, 4, 5]  # finger first: the header names the values, not their position
    columns = {"time": times, "sample": np.arange(frames) * 3, **{PANDA_NAMES[i]: raw[:, i] for i in order}}
    write_wide_csv(examples_dir / "data" / "wide_contract.csv", columns)
    source = {"csv": "data/wide_contract.csv", "index": {"timestamp": "time", "unit": "s"}}
    config = panda_config(examples_dir, "wide_csv_contract", source, CONTRACT_MAP, ignore=["sample"])

    plan = compile_config(config)
    (csv_plan,) = plan.segments[0].sources
    assert isinstance(csv_plan, CsvSourcePlan) and csv_plan.names == ("sample", *(PANDA_NAMES[i] for i in order))
    batches = list(csv_kind._batches(csv_plan))
    assert len(batches) > 5 and sum(b.num_rows for b in batches) == frames

    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "time", _expected_ns(times), q, [0, 1, 57, 123, 199])

    write_wide_csv(examples_dir / "data" / "wide_contract_b.csv", columns)  # diff sees a csv source's file change
    moved = panda_config(
        examples_dir, "wide_csv_contract_b", {**source, "csv": "data/wide_contract_b.csv"}, CONTRACT_MAP, ignore=["sample"]
    )
    changed = run_cli("diff", str(config), str(moved))
    assert changed.code == 0 and "wide_contract_b.csv" in changed.out, changed.err


def test_wide_parquet_by_row_groups_drives_the_panda_and_matches_pinocchio(
    examples_dir: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No `column`: one column per URDF joint, in radians and metres, a sequence index; `names` picks the value
    columns (in another order than the file's), so the text column beside them is never read."""
    monkeypatch.setattr(parquet_kind, "PARQUET_BATCH_ROWS", 16)
    frames = 150
    q = random_panda_q(examples_dir, frames, seed=52)
    frame = 100 + 2 * np.arange(frames)
    columns: dict[str, object] = {"operator": ["bob"] * frames, **{PANDA_JOINTS[i]: q[:, i] for i in range(8)}, "frame": frame}
    write_wide_parquet(examples_dir / "data" / "wide_radians.parquet", columns, row_group_size=40)
    assert pq.ParquetFile(examples_dir / "data" / "wide_radians.parquet").metadata.num_row_groups == 4
    names = list(reversed(PANDA_JOINTS))
    source = {"parquet": "data/wide_radians.parquet", "index": "frame", "names": names}
    config = panda_config(examples_dir, "wide_parquet_radians", source, {name: name for name in PANDA_JOINTS})

    (parquet_plan,) = compile_config(config).segments[0].sources
    assert isinstance(parquet_plan, ParquetSourcePlan) and parquet_plan.column is None and parquet_plan.names == tuple(names)
    assert [b.num_rows for b in parquet_kind._batches(parquet_plan)] == [16] * 9 + [6]  # bounded batches, not the file

    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "frame", [int(f) for f in frame], q, [0, 39, 40, 149])


def test_wide_csv_out_of_order_across_blocks_is_sorted_and_matches_pinocchio(
    examples_dir: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Rows out of time order across blocks: the streamed read stops, the source is read whole and sorted (the
    ordering machinery every kind shares), with a note; a duration index in milliseconds."""
    monkeypatch.setattr(csv_kind, "CSV_BLOCK_BYTES", 4096)
    frames = 120
    q = random_panda_q(examples_dir, frames, seed=53)
    raw = panda_contract_raw(q)
    shuffled = np.r_[60:120, 0:60]  # the second half of the log first
    times_ms = np.arange(frames) * 20
    columns = {"t_ms": times_ms[shuffled], **{name: raw[shuffled, i] for i, name in enumerate(PANDA_NAMES)}}
    write_wide_csv(examples_dir / "data" / "wide_shuffled.csv", columns)
    source = {"csv": "data/wide_shuffled.csv", "index": {"duration": "t_ms", "unit": "ms"}}
    config = panda_config(examples_dir, "wide_csv_shuffled", source, CONTRACT_MAP)
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert "out of t_ms order" in result.err
    durations = [timedelta(milliseconds=int(t)) for t in times_ms]  # a duration timeline reads back as time deltas
    assert_panda_fk(examples_dir, Path(result.out.strip()), "t_ms", durations, q, [0, 59, 60, 119])  # type: ignore[arg-type]


def test_chunks_hold_one_vector_per_row_in_blocks_of_bounded_size(tmp_path: Path) -> None:
    rows = 5000
    values = np.random.default_rng(3).normal(size=(rows, 3))
    write_wide_csv(tmp_path / "w.csv", {"frame": np.arange(rows), "a": values[:, 0], "b": values[:, 1], "c": values[:, 2]})
    document = Document(tmp_path / "config.yaml", {}, {})
    plan = csv_kind.compile_source("s", {"csv": "w.csv", "index": "frame", "names": ["c", "a"]}, document, tmp_path)
    chunks = list(vector_chunks(csv_kind._batches(plan), plan, "/s"))
    assert all(chunk.num_rows <= BLOCK_ROWS for chunk in chunks) and sum(c.num_rows for c in chunks) == rows
    batches = [chunk.to_record_batch() for chunk in chunks]
    got = np.concatenate([np.asarray(b.column("urdf_pipeline:joint_values").flatten().to_pylist()) for b in batches])
    np.testing.assert_array_equal(got, values[:, [2, 0]])
    assert np.concatenate([b.column("frame").to_numpy() for b in batches]).tolist() == list(range(rows))


@pytest.mark.parametrize(
    ("case", "tail", "expected"),
    [
        ("ragged", "12.5,1,2,3", "line 1203: Expected 9 columns, got 4"),
        ("text", "12.5,1,2,3,-90,five,90,0,10", "column 'j5': line 1203: CSV conversion error to double: invalid value 'five'"),
        ("no_time", ",1,2,3,-90,0,90,0,10", "index column 'time' of"),
    ],
    ids=["ragged", "text", "no_time"],
)
def test_bad_rows_beyond_the_first_block_stop_the_run_with_one_located_error(
    examples_dir: Path, run_cli, monkeypatch: pytest.MonkeyPatch, case: str, tail: str, expected: str
) -> None:
    """validate reads the first block only, so it accepts the file; the run stops at the bad row, names it, writes nothing."""
    monkeypatch.setattr(csv_kind, "CSV_BLOCK_BYTES", 8192)
    frames = 1201
    raw = panda_contract_raw(random_panda_q(examples_dir, frames, seed=54))
    columns = {"time": np.arange(frames) / 100, **{name: raw[:, i] for i, name in enumerate(PANDA_NAMES)}}
    name = f"wide_bad_{case}"
    write_wide_csv(examples_dir / "data" / f"{name}.csv", columns, extra_lines=[tail])
    config = panda_config(examples_dir, name, {"csv": f"data/{name}.csv", "index": {"timestamp": "time"}}, CONTRACT_MAP)
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 1 and not result.out.strip()
    (line,) = [text for text in result.err.splitlines() if text.startswith("error")]
    assert line.startswith(f"error: {config}:") and expected in line, line
    assert not (examples_dir / "out" / "sources" / f"{name}.rrd").exists()


def test_describe_takes_the_names_from_the_header(tmp_path: Path) -> None:
    document = Document(tmp_path / "config.yaml", {}, {})
    write_wide_csv(tmp_path / "log.csv", {"time": np.arange(4) / 10, "shoulder": np.zeros(4), "elbow": np.ones(4)})
    described = KINDS["csv"].describe("arm", str(tmp_path / "log.csv"), None, document)
    assert described.kind == "csv" and described.names == ("shoulder", "elbow") and described.segment == "log"
    assert described.fields == (EntryField("index", {"timestamp": "time", "unit": "s"}, described.fields[0].comment),)
    with pytest.raises(UserError, match="takes no #PART"):
        KINDS["csv"].describe("arm", str(tmp_path / "log.csv"), "elbow", document)

    (tmp_path / "noted.csv").write_text("frame,a,note,b\n0,1,x,2\n1,1,y,2\n", encoding="utf-8")
    noted = KINDS["csv"].describe("arm", str(tmp_path / "noted.csv"), None, document)
    assert noted.names == ("a", "b") and noted.fields[0] == EntryField("index", "frame", noted.fields[0].comment)
    assert noted.fields[1].key == "names" and noted.fields[1].value == ["a", "b"] and "note" in noted.fields[1].comment

    write_wide_parquet(tmp_path / "wide.parquet", {"frame_index": np.arange(3), "j1": np.zeros(3), "j2": np.zeros(3)})
    wide = KINDS["parquet"].describe("arm", str(tmp_path / "wide.parquet"), None, document)
    assert wide.kind == "parquet" and wide.names == ("j1", "j2") and [f.key for f in wide.fields] == ["index"]


def test_init_scaffolds_a_config_from_a_wide_csv_that_validates_and_runs(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, 30, seed=55)
    columns = {"frame": np.arange(30), **{name: q[:, i] for i, name in enumerate(PANDA_JOINTS)}}
    write_wide_csv(examples_dir / "data" / "wide_for_init.csv", columns)
    config = examples_dir / "wide_init.yaml"
    urdf, data = examples_dir / "robots" / "panda.urdf", examples_dir / "data" / "wide_for_init.csv"
    result = run_cli("init", "--urdf", str(urdf), "--source", str(data), "-o", str(config))
    assert result.code == 0, result.err
    data = yaml.safe_load(config.read_text(encoding="utf-8"))
    (source,) = data["sources"].values()
    assert source == {"csv": "data/wide_for_init.csv", "index": "frame"}
    (robot,) = data["robots"].values()
    assert sorted(robot["joints"]["map"]) == sorted(PANDA_JOINTS)
    assert run_cli("validate", str(config)).code == 0
    plan = compile_config(config)
    assert module_for(plan.segments[0].sources[0]) is csv_kind


def test_a_glob_of_csv_files_gives_one_segment_per_file(examples_dir: Path, run_cli) -> None:
    """`csv: logs/*.csv` as for every file kind: one segment per file, named by its stem, each checked against pinocchio."""
    trajectories = {}
    for seed, stem in ((56, "run_a"), (57, "run_b")):
        q = random_panda_q(examples_dir, 25, seed=seed)
        trajectories[stem] = q
        columns = {"step": np.arange(25), **{name: q[:, i] for i, name in enumerate(PANDA_JOINTS)}}
        write_wide_csv(examples_dir / "data" / "wide_runs" / f"{stem}.csv", columns)
    source = {"csv": "data/wide_runs/*.csv", "index": "step"}
    config = panda_config(examples_dir, "{stem}", source, {name: name for name in PANDA_JOINTS})
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    written = sorted(Path(line) for line in result.out.split())
    assert [p.stem for p in written] == ["run_a", "run_b"]
    for path in written:
        assert_panda_fk(examples_dir, path, "step", list(range(25)), trajectories[path.stem], [0, 24])

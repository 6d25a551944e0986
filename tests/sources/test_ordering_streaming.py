"""The time-order check streams: rows in order go on as they come, and every other case ends as the whole-source
check (`in_memory=True`, the behaviour before streaming) ends: the same rows, the same error, the same note."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import Chunk, LazyChunkStream

from urdf_pipeline.errors import UserError, Where
from urdf_pipeline.logs import command_logging
from urdf_pipeline.sources.ordering import (
    BLOCK_ROWS,
    ROW_ID,
    NeedsSorting,
    in_blocks,
    in_time_order,
    needs_sorting,
    sorted_in_memory,
    with_sorting_retry,
)

PATH = Path("/data/run.parquet")


@pytest.fixture(autouse=True)
def notes_on_stderr() -> Iterator[None]:
    """The notes as the command line prints them (they go to the `urdf_pipeline` logger)."""
    with command_logging(logging.INFO):
        yield


@dataclass(frozen=True)
class FakePlan:
    name: str = "arm_state"
    duplicates: str = "error"
    where: Where | None = Where(Path("c.yaml"), 7)


def chunk(frames: list[int] | np.ndarray, first_value: int = 0) -> Chunk:
    """Rows on the `frame` timeline; each row's value is its row number in the file, to see which rows stay."""
    frames = np.asarray(frames, dtype=np.int64)
    values = np.arange(first_value, first_value + len(frames), dtype=np.float64)
    return Chunk.from_columns("/q", indexes=[rr.TimeColumn("frame", sequence=frames)], columns=rr.Scalars.columns(scalars=values))


def chunks_of(*runs: list[int]) -> list[Chunk]:
    out, row = [], 0
    for frames in runs:
        out.append(chunk(frames, row))
        row += len(frames)
    return out


def rows_of(chunks: list[Chunk]) -> list[tuple[int, float]]:
    """(frame, row number in the file) of every row, in stream order."""
    pairs: list[tuple[int, float]] = []
    for c in chunks:
        batch = c.to_record_batch()
        frames = batch.column("frame").to_pylist()
        values = batch.column("Scalars:scalars").flatten().to_pylist()
        pairs += zip(frames, values, strict=True)
    return pairs


def run(chunks: list[Chunk], policy: str = "error", in_memory: bool = False) -> list[Chunk]:
    return list(in_time_order(LazyChunkStream.from_iter(chunks), "frame", FakePlan(duplicates=policy), PATH, in_memory=in_memory))


def outcome(chunks: list[Chunk], policy: str, in_memory: bool, capsys: pytest.CaptureFixture[str]) -> tuple[object, str]:
    """The rows passed on, or the error's text; and what was printed."""
    try:
        result: object = rows_of(run(chunks, policy, in_memory))
    except UserError as exc:
        result = str(exc)
    return result, capsys.readouterr().err


def test_rows_in_order_go_on_chunk_by_chunk_untouched() -> None:
    log: list[str] = []
    size = BLOCK_ROWS  # chunks of a block's size go on as they are; smaller ones are joined (next test)
    originals = [chunk(np.arange(k * size, (k + 1) * size), k * size) for k in range(8)]

    def reader() -> Iterator[Chunk]:
        for k, c in enumerate(originals):
            log.append(f"pull {k}")
            yield c

    stream = in_time_order(LazyChunkStream.from_iter(reader()), "frame", FakePlan(), PATH)
    passed = []
    for k, c in enumerate(stream):
        log.append(f"yield {k}")
        passed.append(c)
    for k in range(len(originals) - 2):
        assert log.index(f"yield {k}") < log.index(f"pull {k + 2}"), log
    assert [c.to_record_batch() for c in passed] == [c.to_record_batch() for c in originals]  # the same row ids


def test_small_chunks_in_order_are_joined_into_blocks() -> None:
    """A source of small chunks (an .rrd logged row by row) gives blocks of about BLOCK_ROWS rows, in order."""
    originals = [chunk(np.arange(k * 100, k * 100 + 100), k * 100) for k in range(50)]
    passed = run(originals)
    assert [c.num_rows for c in passed] == [2100, 2100, 800] if BLOCK_ROWS == 2048 else len(passed) < 50
    assert rows_of(passed) == rows_of(originals)


def test_a_large_chunk_is_cut_into_blocks() -> None:
    """A reader's large chunk (Rerun's HDF5 reader gives ~2 MB ones) is cut into blocks, so the FK's batches, and the
    memory they take, stay bounded whatever the source's length."""
    big = [chunk(np.arange(0, 10 * BLOCK_ROWS + 5)), chunk(np.arange(10 * BLOCK_ROWS + 5, 11 * BLOCK_ROWS + 5), 10 * BLOCK_ROWS + 5)]
    passed = run(big)
    assert [c.num_rows for c in passed] == [BLOCK_ROWS] * 10 + [5, BLOCK_ROWS]
    assert rows_of(passed) == rows_of(big)
    unordered = list(LazyChunkStream.from_iter(in_blocks(LazyChunkStream.from_iter(iter(big)))))  # no index to check
    assert [c.num_rows for c in unordered] == [BLOCK_ROWS] * 10 + [5, BLOCK_ROWS] and rows_of(unordered) == rows_of(big)


def test_keep_last_across_a_chunk_boundary(capsys: pytest.CaptureFixture[str]) -> None:
    chunks = chunks_of([0, 1, 2, 3], [3, 3, 4, 5], [5], [6, 7])
    passed = run(chunks, "keep_last")
    note = capsys.readouterr().err
    assert rows_of(passed) == [(0, 0), (1, 1), (2, 2), (3, 5), (4, 6), (5, 8), (6, 9), (7, 10)]
    assert note == "note: source 'arm_state': 3 rows of run.parquet repeat a frame value; kept the last of each (duplicates: keep_last)\n"
    assert ROW_ID in passed[0].to_record_batch().schema.names
    assert outcome(chunks, "keep_last", True, capsys) == (rows_of(passed), note)


def test_repeats_across_a_chunk_boundary_are_the_same_error(capsys: pytest.CaptureFixture[str]) -> None:
    chunks = chunks_of([0, 1, 2], [2, 2, 3], [4, 4])
    with pytest.raises(UserError) as raised:
        run(chunks)
    assert str(raised.value) == outcome(chunks, "error", True, capsys)[0]
    assert "has 3 rows whose frame repeats an earlier row's; the first: frame = 2 at rows 2, 3, 4 (counting from 0)" in str(raised.value)
    assert raised.value.where == FakePlan().where


def test_a_long_run_of_one_value_is_counted_to_its_end(capsys: pytest.CaptureFixture[str]) -> None:
    chunks = chunks_of([0, 1, 1], [1, 1], [1, 1, 2], [3, 3])
    streamed = outcome(chunks, "error", False, capsys)
    assert streamed == outcome(chunks, "error", True, capsys)
    assert "has 6 rows whose frame repeats" in str(streamed[0]) and "frame = 1 at rows 1, 2, 3, 4 and 2 more" in str(streamed[0])


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("policy", ["error", "keep_last"])
def test_streamed_and_whole_agree_on_rows_in_order(seed: int, policy: str, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(seed)
    repeat = 0.05 + 0.04 * seed  # how often a row repeats the previous row's frame
    frames = np.cumsum(rng.choice([0, 1, 2], size=int(rng.integers(1, 60)), p=[repeat, 0.7 * (1 - repeat), 0.3 * (1 - repeat)]))
    cuts = np.sort(rng.choice(np.arange(1, len(frames) + 1), size=min(5, len(frames)), replace=False))
    chunks = chunks_of(*[list(part) for part in np.split(frames, cuts) if len(part)])
    assert outcome(chunks, policy, False, capsys) == outcome(chunks, policy, True, capsys)


def test_rows_out_of_order_ask_to_be_read_whole(capsys: pytest.CaptureFixture[str]) -> None:
    chunks = chunks_of([3, 4, 5], [0, 1, 2])
    with pytest.raises(NeedsSorting) as raised:
        run(chunks)
    assert raised.value.source == "arm_state" and raised.value.path == PATH
    assert needs_sorting(RuntimeError("wrapped")) is None
    opened: list[bool] = []

    def write() -> list[tuple[int, float]]:  # what a caller does: open the sources, read them to the end
        opened.append(True)
        stream = in_time_order(LazyChunkStream.from_iter(chunks), "frame", FakePlan(), PATH)
        return rows_of(list(stream))

    assert with_sorting_retry(write) == [(0, 3), (1, 4), (2, 5), (3, 0), (4, 1), (5, 2)]
    assert len(opened) == 2
    assert capsys.readouterr().err == (
        "note: source 'arm_state': rows of run.parquet are out of frame order (6 rows moved); sorted by frame, stably\n"
    )
    with sorted_in_memory():  # every source read whole: as before streaming
        assert rows_of(run(chunks)) == [(0, 3), (1, 4), (2, 5), (3, 0), (4, 1), (5, 2)]
    with sorted_in_memory("another_source"), pytest.raises(NeedsSorting):
        run(chunks)


def test_a_disorder_after_a_repeat_is_judged_whole(capsys: pytest.CaptureFixture[str]) -> None:
    chunks = chunks_of([5, 6, 6], [1, 1])  # the first repeat in time is 1, not 6
    with pytest.raises(NeedsSorting):
        run(chunks)
    assert "frame = 1 at rows 3, 4" in str(outcome(chunks, "error", True, capsys)[0])


def test_chunks_without_the_timeline_are_not_checked() -> None:
    other = Chunk.from_columns("/q", indexes=[rr.TimeColumn("other", sequence=[9, 9])], columns=rr.Scalars.columns(scalars=[0.0, 1.0]))
    chunks = [*chunks_of([0, 1], [2, 3]), other, chunk([0, 0])]

    def rows(passed: list[Chunk]) -> list[dict]:  # every row with its columns, row ids left out (small chunks are joined)
        return [row for c in passed for row in c.to_record_batch().drop_columns([ROW_ID]).to_pylist()]

    assert rows(run(chunks)) == rows(chunks) == rows(run(chunks, in_memory=True))
    with pytest.raises(NeedsSorting):  # rows already dropped for a repeat cannot come back: judged whole
        run([*chunks_of([0, 1], [1, 3]), other], "keep_last")


def test_a_reader_error_names_the_file() -> None:
    def corrupt() -> Iterator[Chunk]:
        yield chunk([0, 1])
        raise RuntimeError("decoding failed: bad page\nmore detail")

    stream = in_time_order(LazyChunkStream.from_iter(corrupt()), "frame", FakePlan(), PATH)
    with pytest.raises(UserError, match=r"cannot read /data/run.parquet, it is probably corrupt: decoding failed: bad page$"):
        list(stream)

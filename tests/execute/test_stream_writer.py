"""The recording is written while it is read: the same content as a collected store, in chunks about as large as the
collected store's (never confetti)."""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pyarrow as pa
import pytest
import rerun as rr
from rerun.chunk import Chunk, LazyChunkStream, OptimizationProfile, RrdReader

from urdf_pipeline.compile import compile_config
from urdf_pipeline.execute import execute
from urdf_pipeline.execute import segment as segment_module
from urdf_pipeline.execute.stream_writer import drain_streams
from urdf_pipeline.sources import CallbackErrors

ROW_ID = "rerun.controls.RowId"


def _collected(streams: list, sink: Callable[[object], None], errors: object = None) -> None:
    """What the pipeline did before it streamed: merge, collect(OBJECT_STORE), write (the sink calls `write_rrd`)."""
    sink(LazyChunkStream.merge(*streams).collect(optimize=OptimizationProfile.OBJECT_STORE))


def _to_file(path: Path) -> Callable[[LazyChunkStream], None]:
    return lambda merged: merged.write_rrd(path, application_id="app", recording_id="rec")


def _content(path: Path) -> tuple[dict[str, pa.Table], list[str]]:
    """Per (entity, temporal columns): every row, sorted on every column but the row id; and the static chunks."""
    temporal: dict[str, list[pa.Table]] = {}
    static: list[str] = []
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        batch = batch.drop_columns([ROW_ID]) if ROW_ID in batch.schema.names else batch
        if chunk.is_static:
            static.append(f"{chunk.entity_path} {pa.Table.from_batches([batch]).to_pylist()}")
            continue
        key = f"{chunk.entity_path} {sorted(batch.schema.names)}"
        table = pa.Table.from_batches([batch.replace_schema_metadata({})])
        temporal.setdefault(key, []).append(table.select(sorted(table.column_names)))
    tables = {}
    for key, parts in temporal.items():
        table = pa.concat_tables(parts)
        rows = sorted(table.to_pylist(), key=repr)
        tables[key] = rows
    return tables, sorted(static)


def _chunk_counts(path: Path) -> tuple[int, list[int]]:
    chunks = list(RrdReader(path).stream())
    return len(chunks), [chunk.num_rows for chunk in chunks if not chunk.is_static]


@pytest.mark.parametrize("config", ["demo.yaml", "bimanual_pandas.yaml", "aloha_bimanual.yaml"])
def test_streamed_recording_equals_the_collected_one(examples_dir: Path, config: str, monkeypatch: pytest.MonkeyPatch) -> None:
    compiled = compile_config(examples_dir / config)
    plan = compiled.for_segment(compiled.segments[0])
    streamed = execute(plan, quiet=True).output.rename(examples_dir / "streamed.rrd")
    monkeypatch.setattr(segment_module, "drain_streams", _collected)
    collected = execute(plan, quiet=True).output

    assert _content(streamed) == _content(collected)
    streamed_chunks, streamed_rows = _chunk_counts(streamed)
    collected_chunks, _ = _chunk_counts(collected)
    assert streamed_chunks <= 2 * collected_chunks, (streamed_chunks, collected_chunks)
    assert streamed_chunks <= collected_chunks + 2 * len(plan.robots) + 4  # a few more at most: not confetti


def test_an_error_raised_while_reading_is_raised_as_itself(tmp_path: Path) -> None:
    class Refused(Exception):
        pass

    def failing():
        yield Chunk.from_columns("/x", indexes=[rr.TimeColumn("frame", sequence=[0])], columns=rr.Scalars.columns(scalars=[0.0]))
        raise Refused("source said no")

    errors = CallbackErrors()
    with pytest.raises(Refused, match="source said no"):
        drain_streams([errors.wrap_stream(LazyChunkStream.from_iter(failing()))], _to_file(tmp_path / "x.rrd"), errors)


def _endless() -> Iterator[Chunk]:
    frame = 0
    while True:
        yield Chunk.from_columns("/x", indexes=[rr.TimeColumn("frame", sequence=[frame])], columns=rr.Scalars.columns(scalars=[0.0]))
        frame += 1
        time.sleep(0.001)


def _writers() -> list[threading.Thread]:
    """The writer threads that have not returned. Not `is_alive()`: after an interrupted `join`, Python 3.11 says False
    of a thread that still runs (CPython gh-90882); a thread leaves `enumerate()` only once its function returned."""
    return [t for t in threading.enumerate() if t.name == "urdf-pipeline-writer"]


def test_ctrl_c_stops_a_write_that_runs_on_rerun_threads(tmp_path: Path) -> None:
    """An endless source: only the cancellation that Ctrl-C triggers can end the write, and it does; the writer has
    returned before the KeyboardInterrupt reaches the caller (Rerun's threads would otherwise run Python while the
    interpreter finalizes, and abort it)."""
    main = threading.main_thread().ident
    assert main is not None
    threading.Timer(0.5, signal.pthread_kill, (main, signal.SIGINT)).start()  # while drain_streams waits for the writer
    errors = CallbackErrors()
    with pytest.raises(KeyboardInterrupt):
        drain_streams([errors.wrap_stream(LazyChunkStream.from_iter(_endless()))], _to_file(tmp_path / "x.rrd"), errors)
    assert not _writers()


def test_ctrl_c_as_the_writer_starts_still_cancels_it(tmp_path: Path) -> None:
    """The signal comes while the main thread starts the writer (the sink signals as soon as it runs): the write is
    cancelled and waited for all the same."""
    main = threading.main_thread().ident
    assert main is not None

    def signalling_sink(merged: LazyChunkStream) -> None:
        signal.pthread_kill(main, signal.SIGINT)
        _to_file(tmp_path / "x.rrd")(merged)

    errors = CallbackErrors()
    with pytest.raises(KeyboardInterrupt):
        drain_streams([errors.wrap_stream(LazyChunkStream.from_iter(_endless()))], signalling_sink, errors)
    assert not _writers()


def test_a_signal_whose_handler_does_not_raise_leaves_the_write_alone(tmp_path: Path) -> None:
    """Only a handler that raises (Ctrl-C's, SIGTERM's in a run) stops the write; one that does not is called, and the
    write goes on to its end."""
    main = threading.main_thread().ident
    assert main is not None
    called: list[int] = []

    def finite() -> Iterator[Chunk]:
        for frame in range(200):
            yield Chunk.from_columns("/x", indexes=[rr.TimeColumn("frame", sequence=[frame])], columns=rr.Scalars.columns(scalars=[0.0]))
            if frame == 20:
                signal.pthread_kill(main, signal.SIGINT)
            time.sleep(0.001)

    previous = signal.signal(signal.SIGINT, lambda number, frame: called.append(number))
    try:
        errors = CallbackErrors()
        drain_streams([errors.wrap_stream(LazyChunkStream.from_iter(finite()))], _to_file(tmp_path / "x.rrd"), errors)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert called == [signal.SIGINT]
    assert sum(chunk.num_rows for chunk in RrdReader(tmp_path / "x.rrd").stream() if not chunk.is_static) == 200
    assert not _writers()


def test_a_write_error_names_the_file_and_keeps_the_previous_one(examples_dir: Path) -> None:
    """The file system refuses the write part-way (a file size limit stands in for a full disk): exit 1, one error
    naming the output, the previous recording untouched, no partial file."""
    import subprocess
    import sys

    config = examples_dir / "demo.yaml"
    output = examples_dir / "out" / "episode_000.rrd"
    first = subprocess.run([sys.executable, "-m", "urdf_pipeline", "run", str(config)], capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    before = output.read_bytes()
    code = (
        "import resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
        "resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 20, 1 << 20)); "
        f"from urdf_pipeline.cli import main; rc = main(['run', {str(config)!r}, '--force']); "
        # main's own answer: once, under load, a C++ thread aborted at interpreter exit under this file size limit
        "sys.stdout.flush(); sys.stderr.flush(); import os; os._exit(rc)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 1, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and f"cannot write {output}" in errors[0], result.stderr
    assert "Traceback" not in result.stderr and "WARN" not in result.stderr  # one line, not Rerun's too
    assert output.read_bytes() == before
    assert not [p for p in output.parent.iterdir() if ".partial-" in p.name]

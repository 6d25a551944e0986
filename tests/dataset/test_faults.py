"""Outputs are safe and faults end cleanly: a file the tool did not write is never replaced (not even with --force), an
output folder that takes no files is found before computing, SIGTERM stops a run as Ctrl-C does (exit 143, workers
gone, only complete files, the summary printed), the partial files a SIGKILL left are removed by the next run, and
worker temporary folders do not outlive the run."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import Chunk, LazyChunkStream

from urdf_pipeline.examples import write_lerobot_dataset

from ..dataset_helpers import SO101_JOINTS, edit_config, isolated_examples, status_lines, store_ids

WAIT = 120.0  # seconds a subprocess may take to reach a state; a bound against hangs, not a measurement


@pytest.fixture
def so101_dataset(examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))  # robots/ and data/ link to the session's examples
    return isolated_examples(examples_dir, tmp_path / "run")


def _outputs(config: Path) -> Path:
    return config.parent / "out" / "so101_dataset"


def _partials(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.rglob("*") if ".partial" in p.name) if directory.exists() else []


def _foreign_recording(path: Path) -> None:
    """A valid Rerun recording that urdf-pipeline did not write (no urdf_pipeline property)."""
    store = LazyChunkStream.from_iter([Chunk.from_property("someone_else", rr.AnyValues(note="mine"))]).collect()
    path.parent.mkdir(parents=True, exist_ok=True)
    store.write_rrd(path, application_id="so101_dataset", recording_id="episode_000001")


def _assert_refused(err: str, path: Path) -> None:
    assert "Traceback" not in err, err
    assert f"cannot write {path}: it exists" in err, err
    assert "never overwrites a file it did not write (not even with --force)" in err, err
    assert "delete or move it, or choose another output path" in err, err


# --- never overwrite a file the tool did not write ---------------------------------------------------------------


@pytest.mark.parametrize(
    "make",
    [
        pytest.param(lambda p: p.write_text("notes I keep here\n"), id="text"),
        pytest.param(_foreign_recording, id="foreign-rrd"),
        pytest.param(lambda p: p.mkdir(parents=True), id="directory"),
    ],
)
def test_a_file_the_tool_did_not_write_is_never_replaced(so101_dataset: Path, run_cli, make: Callable[[Path], None]) -> None:
    assert run_cli("run", str(so101_dataset), "--jobs", "1").code == 0
    outputs = _outputs(so101_dataset)
    victim = outputs / "episode_000001.rrd"
    victim.unlink()
    make(victim)
    before = {p.name: p.stat().st_mtime_ns for p in outputs.iterdir()}

    result = run_cli("run", str(so101_dataset), "--jobs", "1", "--force")

    assert result.code == 1, result.err
    _assert_refused(result.err, victim)
    assert {p.name: p.stat().st_mtime_ns for p in outputs.iterdir()} == before, "refused before writing anything"


def test_our_own_recordings_are_replaced_with_force(so101_dataset: Path, run_cli) -> None:
    assert run_cli("run", str(so101_dataset), "--jobs", "1").code == 0
    result = run_cli("run", str(so101_dataset), "--jobs", "1", "--force")
    assert result.code == 0, result.err
    assert set(status_lines(result.err).values()) == {"written"}


def test_a_foreign_manifest_is_never_replaced(so101_dataset: Path, run_cli) -> None:
    manifest = _outputs(so101_dataset) / "so101_dataset.manifest.json"
    manifest.parent.mkdir(parents=True)
    manifest.write_text('{"name": "package.json of some project"}\n')
    result = run_cli("run", str(so101_dataset), "--jobs", "1", "--force")
    assert result.code == 1
    _assert_refused(result.err, manifest)
    assert "no 'urdf_pipeline' key" in result.err
    assert json.loads(manifest.read_text()) == {"name": "package.json of some project"}
    assert sorted(p.name for p in manifest.parent.iterdir()) == [manifest.name]


def test_a_foreign_blueprint_is_never_replaced(so101_dataset: Path, run_cli) -> None:
    blueprint = _outputs(so101_dataset) / "so101_dataset.rbl"
    _foreign_recording(blueprint)
    result = run_cli("run", str(so101_dataset), "--jobs", "1")
    assert result.code == 1
    _assert_refused(result.err, blueprint)
    assert "not a Rerun blueprint" in result.err


# --- an output folder that takes no files: found before computing ------------------------------------------------


def test_an_output_folder_under_a_file_is_found_before_computing(so101_dataset: Path, run_cli) -> None:
    """Works as root too: no permission is involved, the folder's parent is a regular file."""
    blocker = so101_dataset.parent / "blocker"
    blocker.write_text("a file where a folder should be\n")
    edit_config(so101_dataset, lambda d: d["output"].update(path="blocker/{segment}.rrd", manifest="out/so101.manifest.json"))

    result = run_cli("run", str(so101_dataset), "--jobs", "1")

    assert result.code == 1, result.err
    assert "Traceback" not in result.err and "internal error" not in result.err
    assert f"cannot write to {blocker}: {blocker} is not a directory" in result.err
    assert "written" not in result.err, "refused before computing anything"
    assert not (so101_dataset.parent / "out").exists() or not any((so101_dataset.parent / "out").rglob("*.rrd"))


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only (0o555) folder anyway")
def test_a_read_only_output_folder_is_found_before_computing(so101_dataset: Path, run_cli) -> None:
    outputs = _outputs(so101_dataset)
    outputs.mkdir(parents=True)
    outputs.chmod(0o555)
    try:
        result = run_cli("run", str(so101_dataset), "--jobs", "1")
    finally:
        outputs.chmod(0o755)
    assert result.code == 1, result.err
    assert "Traceback" not in result.err
    assert f"cannot write to {outputs}" in result.err
    assert not any(outputs.iterdir())


# --- signals, killed runs, temporary folders ---------------------------------------------------------------------


def _long_dataset(config: Path, episodes: int = 8, frames: int = 100_000, beyond_limits: int | None = None) -> None:
    """Episodes long enough that a run is still going when the test signals it (values 0: inside every limit; the
    episode `beyond_limits` at 500 degrees: that segment fails)."""
    values = [np.full((frames, len(SO101_JOINTS)), 500.0 if e == beyond_limits else 0.0) for e in range(episodes)]
    write_lerobot_dataset(config.parent / "long_so101", values, SO101_JOINTS)
    edit_config(config, lambda d: d["sources"]["so101"].update(lerobot="long_so101"))


def _start(config: Path, scratch: Path) -> subprocess.Popen[str]:
    scratch.mkdir(exist_ok=True)
    env = {**os.environ, "TMPDIR": str(scratch)}
    command = [sys.executable, "-m", "urdf_pipeline", "run", str(config), "--jobs", "2"]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)


def _living_stats() -> Iterator[tuple[int, list[str]]]:
    """Each living (not zombie) process and the fields of its /proc stat after the name: state, ppid, pgrp, session."""
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue  # gone meanwhile
            if fields[0] != "Z":
                yield int(entry.name), fields


def _parents() -> dict[int, int]:
    return {pid: int(fields[1]) for pid, fields in _living_stats()}


def _session(sid: int) -> set[int]:
    """The living processes of session `sid`: a run started in a session of its own, every process it ever forked
    (a worker forked after the test looked at the run's children included), wherever they were reparented."""
    return {pid for pid, fields in _living_stats() if int(fields[3]) == sid}


def _descendants(pid: int) -> set[int]:
    parents = _parents()
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def _wait_for(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not condition():
        assert time.monotonic() < deadline, f"gave up waiting for {what}"
        time.sleep(0.05)


def _living(pids: set[int]) -> set[int]:
    return pids & set(_parents())


def _first_segment_written(process: subprocess.Popen[str], outputs: Path) -> set[int]:
    """Wait until a segment's recording exists and workers are running; their process ids."""
    _wait_for(lambda: process.poll() is not None or any(outputs.glob("episode_*.rrd")), "the first segment")
    if process.poll() is not None:
        raise AssertionError(f"the run ended (exit {process.returncode}) before the test could signal it:\n{process.communicate()[1]}")
    _wait_for(lambda: len(_descendants(process.pid)) >= 2, "the worker processes")
    return _descendants(process.pid)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to follow child processes")
def test_sigterm_stops_like_ctrl_c(so101_dataset: Path, tmp_path: Path) -> None:
    _long_dataset(so101_dataset)
    outputs = _outputs(so101_dataset)
    scratch = tmp_path / "tmp"
    process = _start(so101_dataset, scratch)
    children = _first_segment_written(process, outputs)

    process.send_signal(signal.SIGTERM)  # the main process only, as `kill PID`: it must stop its workers itself
    out, err = process.communicate(timeout=WAIT)

    assert process.returncode == 143, err
    assert "interrupted (SIGTERM): " in err and "; only complete outputs were kept" in err
    assert "Traceback" not in err
    statuses = status_lines(err)
    assert "interrupted" in statuses.values(), "the summary lists what was stopped"
    assert not _partials(outputs), "partial files were left behind"
    written = sorted(p.name for p in outputs.glob("episode_*.rrd"))
    manifest = json.loads((outputs / "so101_dataset.manifest.json").read_text())
    assert sorted(s["path"] for s in manifest["segments"]) == written, "the manifest lists exactly the complete files"
    for name in written:
        assert store_ids(outputs / name)[1] == name.removesuffix(".rrd")  # readable: complete
    _wait_for(lambda: not _living(children), f"the run's processes {sorted(_living(children))} to end")
    assert not list(scratch.iterdir()), "temporary folders outlived the run"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to follow child processes")
def test_after_sigkill_no_worker_survives_and_the_next_run_cleans_up(so101_dataset: Path, tmp_path: Path) -> None:
    _long_dataset(so101_dataset, episodes=6)
    outputs = _outputs(so101_dataset)
    process = _start(so101_dataset, tmp_path / "tmp")
    children = _first_segment_written(process, outputs)

    process.kill()  # the main process only: its workers must not keep writing without it
    process.communicate(timeout=WAIT)
    _wait_for(lambda: not _living(children), f"the orphaned processes {sorted(_living(children))} to end")
    # and any worker forked after `children` was read (seen once: its partial file, written until it ended, was still
    # there when the next run cleaned up, so that run had to keep it as a live process's)
    _wait_for(lambda: not _session(process.pid), f"the run's session {sorted(_session(process.pid))} to end")
    # What a kill in the middle of a write leaves: a hidden partial file named after a process that is gone.
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = outputs / f".episode_000003.rrd.partial-{dead.pid}"
    stale.write_bytes(b"half a recording")
    live = outputs / f".episode_000004.rrd.partial-{os.getpid()}"  # a running process's: not ours to remove
    live.write_bytes(b"being written")
    unrelated = outputs / f".notes.txt.partial-{dead.pid}"  # not the partial of a file this run writes
    unrelated.write_bytes(b"someone else's")

    again = subprocess.run(
        [sys.executable, "-m", "urdf_pipeline", "run", str(so101_dataset), "--jobs", "1", "--episodes", "0"],
        capture_output=True,
        text=True,
        timeout=WAIT,
        env={**os.environ, "TMPDIR": str(tmp_path / "tmp")},
    )

    assert again.returncode == 0, again.stderr
    assert not stale.exists(), "the stale partial file of a killed run was kept"
    assert live.exists() and unrelated.exists(), "only stale partial files of this run's outputs are removed"
    live.unlink()
    unrelated.unlink()
    assert not _partials(outputs)


def test_worker_temporary_folders_are_removed_after_success_and_failure(so101_dataset: Path, tmp_path: Path) -> None:
    _long_dataset(so101_dataset, episodes=4, frames=20_000)
    scratch = tmp_path / "tmp"
    process = _start(so101_dataset, scratch)
    _, err = process.communicate(timeout=WAIT)
    assert process.returncode == 0, err
    assert not list(scratch.iterdir()), "temporary folders outlived a successful run"

    # One segment fails (values beyond the limits): the run exits 1, and still leaves no temporary folder.
    _long_dataset(so101_dataset, episodes=4, frames=20_000, beyond_limits=2)
    process = _start(so101_dataset, scratch)
    _, err = process.communicate(timeout=WAIT)
    assert process.returncode == 1, err
    assert status_lines(err).get("episode_000002") == "failed", err
    assert not list(scratch.iterdir()), "temporary folders outlived a failed run"


@pytest.mark.parametrize(
    "damage",
    [
        {"files": {"data/x.parquet": ["not a size", 1, "ab"]}},
        {"files": ["a list"]},
        {"blueprint": "a string"},
        {"blueprint": {"path": 7}},
        {"model": ["a list"]},
        {"segments": ["episode_000000", {"segment": 3, "path": None}]},
    ],
)
def test_a_damaged_manifest_of_ours_is_read_as_stale(so101_dataset: Path, run_cli, damage: dict) -> None:
    """A manifest with our key whose entries are of the wrong shape (hand-edited, or committed in a pull request):
    what it says is not trusted, every output is checked again and rewritten; never a crash (exit 70)."""
    assert run_cli("run", str(so101_dataset)).code == 0
    manifest = _outputs(so101_dataset) / "so101_dataset.manifest.json"
    manifest.write_text(json.dumps({**json.loads(manifest.read_text()), **damage}))
    result = run_cli("run", str(so101_dataset))
    assert result.code == 0, result.err
    data = json.loads(manifest.read_text())
    assert all(isinstance(entry, list) and len(entry) == 3 for entry in data["files"].values())
    assert isinstance(data["blueprint"], dict)

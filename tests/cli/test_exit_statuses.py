"""One rule for every command, made at the one exit point (cli/entry.py): Ctrl-C exits 130, SIGTERM 143, a stdout
closed early 141, never with a traceback. `run` stopped mid-dataset: tests/dataset/test_dataset_run.py and
test_faults.py; `serve`: tests/web/test_serve.py; `live` (a followed MCAP file being written, a Foxglove server):
tests/live_views/test_live_command.py."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from urdf_pipeline.errors import ExitCode

from ..dataset_helpers import isolated_examples

WAIT = 60  # seconds: a bound against hangs, not a measurement


def test_every_signal_status_comes_from_one_rule() -> None:
    assert ExitCode.for_signal(signal.SIGINT) == ExitCode.INTERRUPTED == 130
    assert ExitCode.for_signal(signal.SIGTERM) == ExitCode.TERMINATED == 143
    assert ExitCode.for_signal(signal.SIGPIPE) == ExitCode.BROKEN_PIPE == 141


def _command(examples_dir: Path, *arguments: str) -> subprocess.Popen[str]:
    env = {**os.environ, "URDF_PIPELINE_ALLOW_PATHS": str(examples_dir)}
    command = [sys.executable, "-m", "urdf_pipeline", *arguments]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


@pytest.mark.parametrize(("sent", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_validate_stopped_by_a_signal(examples_dir: Path, tmp_path: Path, sent: signal.Signals, status: int) -> None:
    """validate of 300 configs, stopped once the first is done: the signal's status, and `interrupted` last."""
    config = isolated_examples(examples_dir, tmp_path / "many", "demo.yaml")
    configs = [config.with_name(f"demo_{n:03d}.yaml") for n in range(300)]
    for copy in configs:
        shutil.copy(config, copy)
    process = _command(examples_dir, "validate", *map(str, configs))
    assert process.stdout is not None
    first = process.stdout.readline()  # `ok: CONFIG`, one line per config as each is done
    assert first.startswith("ok: "), first
    process.send_signal(sent)
    out, err = process.communicate(timeout=WAIT)
    assert process.returncode == status, err
    assert err.rstrip().endswith("interrupted") and "Traceback" not in err
    assert len(out.splitlines()) < 299, "stopped before the end"


def _with_stdout_closed(examples_dir: Path, arguments: list[str]) -> subprocess.CompletedProcess[str]:
    """The command with a stdout whose reader has already gone (`... | head -c 0`): its first write fails (EPIPE)."""
    read, write = os.pipe()
    os.close(read)
    try:
        env = {**os.environ, "URDF_PIPELINE_ALLOW_PATHS": str(examples_dir)}
        command = [sys.executable, "-m", "urdf_pipeline", *arguments]
        return subprocess.run(command, stdout=write, stderr=subprocess.PIPE, text=True, env=env, timeout=WAIT * 3)
    finally:
        os.close(write)


@pytest.mark.parametrize(
    "arguments",
    [
        ["validate", "{demo}"],
        ["validate", "--format", "json", "{demo}"],
        ["plan", "{demo}"],
        ["diff", "{demo}", "{dataset}"],
        ["check", "{demo}"],
        ["qa", "{dataset}"],
        ["schema"],
        ["init", "--urdf", "{urdf}"],
        ["run", "{dataset}", "--jobs", "1"],
        ["serve", "{site}"],
    ],
    ids=lambda arguments: "-".join(a for a in arguments if not a.startswith("{")),
)
def test_a_stdout_closed_early_is_141_without_a_traceback(examples_dir: Path, tmp_path: Path, arguments: list[str]) -> None:
    demo = isolated_examples(examples_dir, tmp_path / "demo", "demo.yaml")
    dataset = isolated_examples(examples_dir, tmp_path / "dataset")
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("<!doctype html><title>a site</title>\n")
    names = {"demo": demo, "dataset": dataset, "site": site, "urdf": examples_dir / "robots" / "panda.urdf"}
    result = _with_stdout_closed(examples_dir, [a.format(**names) for a in arguments])
    assert result.returncode == 141, result.stderr
    assert "Traceback" not in result.stderr and "Exception ignored" not in result.stderr, result.stderr

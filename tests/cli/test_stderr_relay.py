"""Everything a command says on stderr goes through the `urdf_pipeline` logger at the level of -q / -v: Rerun's own
log lines (written by its Rust side to file descriptor 2) and Python's warnings (numpy's on NaN values) included."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest

from urdf_pipeline.cli import parser
from urdf_pipeline.cli.stderr_relay import relayed
from urdf_pipeline.logs import warnings_logged

RERUN_WARN = "\x1b[2m2026-01-01T00:00:00.123456Z\x1b[0m \x1b[33m WARN\x1b[0m \x1b[2mre_sdk::recording_stream\x1b[0m\x1b[2m:\x1b[0m careful"


def test_rerun_lines_are_ours_at_a_level_and_other_lines_are_kept_as_they_are() -> None:
    assert relayed(RERUN_WARN) == (logging.DEBUG, "rerun: WARN re_sdk::recording_stream: careful", True)
    assert relayed("2026-01-01T00:00:00Z ERROR re_grpc_client::write: dropping all pending messages") == (
        logging.INFO,
        "rerun: ERROR re_grpc_client::write: dropping all pending messages",
        True,
    )
    assert relayed("[2026-01-01T00:00:00Z WARN  re_log_encoding] old format") == (
        logging.DEBUG,
        "rerun: WARN re_log_encoding: old format",
        True,
    )
    assert relayed("2026-01-01T00:00:00Z  INFO re_grpc_server: listening") == (logging.DEBUG, "rerun: INFO re_grpc_server: listening", True)
    assert relayed("urdf-pipeline: [2/5] episode_000001 written") == (logging.WARNING, "urdf-pipeline: [2/5] episode_000001 written", False)
    assert relayed("   ") is None
    assert relayed("::error::forged by a file name\x07") == (logging.WARNING, "\\::error::forged by a file name\\x07", False)
    # the second line of a multi-line Rerun event (a gRPC status and its metadata) stays with it; our lines never do
    assert relayed('- metadata: {"server": "x"}', logging.INFO) == (logging.INFO, 'rerun:   - metadata: {"server": "x"}', True)
    assert relayed("  caused by: no route", logging.DEBUG) == (logging.DEBUG, "rerun:   caused by: no route", True)
    assert relayed("urdf-pipeline: [2/5] episode_000001 written", logging.INFO)[0] == logging.WARNING  # type: ignore[index]
    assert relayed("thread 'main' panicked at src/lib.rs:1", logging.INFO)[0] == logging.WARNING  # type: ignore[index]


def _fake_command(tmp_path: Path, body: str) -> Path:
    """A script whose `schema` command runs `body` (a command's function) instead: the CLI around it is the real one."""
    script = tmp_path / "fake_command.py"
    script.write_text(
        "import os, sys\nfrom urdf_pipeline.cli import main, parser\n\n\ndef fake(args):\n"
        + textwrap.indent(textwrap.dedent(body), "    ")
        + "\n\nparser.cmd_schema = fake\nsys.exit(main(sys.argv[1:]))\n"
    )
    return script


WRITES_TO_FD_2 = r"""
os.write(2, b"\x1b[2m2026-01-01T00:00:00.000Z\x1b[0m \x1b[33m WARN\x1b[0m re_sdk::x: careful\n")
os.write(2, b"2026-01-01T00:00:00Z ERROR re_sdk::y: dropped\n- metadata: {}\n")
os.write(2, b"thread 'writer' panicked at here\n")
print("said on sys.stderr", file=sys.stderr)
os.write(2, b"no newline at the end")
return 0
"""


@pytest.mark.parametrize(
    ("flags", "expected"),
    [
        (["-q"], ["thread 'writer' panicked at here", "said on sys.stderr", "no newline at the end"]),
        (
            [],
            [
                "rerun: ERROR re_sdk::y: dropped",
                "rerun:   - metadata: {}",
                "thread 'writer' panicked at here",
                "said on sys.stderr",
                "no newline at the end",
            ],
        ),
        (
            ["-v"],
            [
                "rerun: WARN re_sdk::x: careful",
                "rerun: ERROR re_sdk::y: dropped",
                "rerun:   - metadata: {}",
                "thread 'writer' panicked at here",
                "said on sys.stderr",
                "no newline at the end",
            ],
        ),
    ],
)
def test_writes_to_file_descriptor_2_reach_stderr_through_the_logger(tmp_path: Path, flags: list[str], expected: list[str]) -> None:
    script = _fake_command(tmp_path, WRITES_TO_FD_2)
    done = subprocess.run([sys.executable, str(script), *flags, "schema"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert sorted(lines) == sorted(expected)  # sys.stderr is written at once, the relayed lines as the thread reads them
    assert lines.index("thread 'writer' panicked at here") < lines.index("no newline at the end"), "fd 2 keeps its order"


def test_a_bug_still_prints_its_traceback_and_ctrl_c_still_interrupts(tmp_path: Path) -> None:
    bug = _fake_command(tmp_path, 'os.write(2, b"before the bug\\n")\nraise RuntimeError("a bug")')
    done = subprocess.run([sys.executable, str(bug), "-q", "schema"], capture_output=True, text=True)
    assert done.returncode == 70
    assert "Traceback (most recent call last)" in done.stderr and "RuntimeError: a bug" in done.stderr
    assert "before the bug" in done.stderr and "internal error (a bug, not your config)" in done.stderr
    stop = _fake_command(tmp_path, "raise KeyboardInterrupt")
    done = subprocess.run([sys.executable, str(stop), "schema"], capture_output=True, text=True)
    assert (done.returncode, done.stderr) == (130, "interrupted\n")


def test_in_process_the_relayed_lines_go_where_the_logger_writes(run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    """cli.main called by a program (here, a test with captured stderr): fd 2 is relayed too, and given back after."""

    def fake(args: object) -> int:
        os.write(2, b"2026-01-01T00:00:00Z ERROR re_sdk::y: dropped\n")
        return 0

    monkeypatch.setattr(parser, "cmd_schema", fake)
    assert run_cli("schema").err == "rerun: ERROR re_sdk::y: dropped\n"
    assert run_cli("-q", "schema").err == ""


def _file_size_limited_run(config: Path, *flags: str) -> subprocess.CompletedProcess[str]:
    """A run whose write the file system refuses part-way (a 1 MiB file size limit): Rerun's writer logs a WARN."""
    code = (
        "import resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
        "resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 20, 1 << 20)); "
        f"from urdf_pipeline.cli import main; rc = main([*{list(flags)!r}, 'run', {str(config)!r}, '--force']); "
        "sys.stdout.flush(); sys.stderr.flush(); import os; os._exit(rc)"
    )
    env = {key: value for key, value in os.environ.items() if key != "RUST_LOG"}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)


def test_rerun_s_own_warning_shows_under_verbose_in_our_format_and_not_under_quiet(examples_dir: Path) -> None:
    config = examples_dir / "demo.yaml"
    verbose = _file_size_limited_run(config, "-v")
    assert verbose.returncode == 1, verbose.stderr
    rerun_lines = [line for line in verbose.stderr.splitlines() if line.startswith("rerun: ")]
    assert rerun_lines and rerun_lines[0].startswith("rerun: WARN re_log_encoding::"), verbose.stderr
    assert "\x1b[" not in verbose.stderr and "[20" not in verbose.stderr and "Z WARN" not in verbose.stderr
    quiet = _file_size_limited_run(config, "-q")
    assert quiet.returncode == 1
    (line,) = quiet.stderr.splitlines()
    assert line.startswith("error: ") and "cannot write" in line


def test_numpy_warnings_on_infinite_values_never_reach_stderr(allow_examples: Path, tmp_path: Path, run_cli) -> None:
    """Infinite values, refused by `nan: error` after the pass: the FK has met them first (numpy's "invalid value
    encountered in sin", silenced where it is expected; any other Python warning goes to the logger at DEBUG)."""
    import numpy as np

    from urdf_pipeline.examples import panda_raw_values, read_urdf, write_joint_parquet

    from ..dataset_helpers import isolated_examples

    config = isolated_examples(allow_examples, tmp_path / "nan", "demo.yaml")
    (config.parent / "data").joinpath("episode_000.parquet").unlink()
    _, panda = read_urdf(allow_examples / "robots" / "panda.urdf")
    values = panda_raw_values(300, panda)
    values[5:50, 2] = np.inf
    write_joint_parquet(config.parent / "data" / "episode_000.parquet", values)
    quiet = run_cli("-q", "run", str(config))
    assert quiet.code == 1
    assert quiet.err.splitlines() and all(line.startswith("error: ") for line in quiet.err.splitlines()), quiet.err
    assert "are NaN or infinite" in quiet.err
    verbose = run_cli("-v", "run", str(config))
    assert verbose.code == 1  # the FK expects them (np.errstate): no warning at all, and any other goes to the logger
    assert "RuntimeWarning" not in verbose.err.replace("urdf-pipeline: python warning: ", "")


def test_a_segment_s_warnings_go_to_the_logger_in_any_process(caplog: pytest.LogCaptureFixture, capsys) -> None:
    """As run_segment does in a pool worker or a Ray task."""
    with caplog.at_level(logging.DEBUG, logger="urdf_pipeline"), warnings_logged():
        warnings.warn("overflow encountered in cast", RuntimeWarning, stacklevel=1)
    assert capsys.readouterr().err == ""
    (record,) = [r for r in caplog.records if "python warning" in r.getMessage()]
    assert record.levelno == logging.DEBUG and "RuntimeWarning: overflow encountered in cast" in record.getMessage()

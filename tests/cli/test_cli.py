"""Exit codes and output shape: user errors exit 1 with one line each, bugs exit 70 with a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from urdf_pipeline.errors import ExitCode

from ..conftest import assert_commands_leave_out


def test_user_error_is_one_line_without_traceback(tmp_path: Path, run_cli) -> None:
    config = tmp_path / "c.yaml"
    config.write_text("version: 1\nsources: [\n")
    result = run_cli("run", str(config))
    assert result.code == 1
    assert result.err.startswith(f"error: {config}:") and "Traceback" not in result.err
    assert len(result.err.strip().splitlines()) == 1


def test_missing_config_file(run_cli, tmp_path: Path) -> None:
    result = run_cli("validate", str(tmp_path / "nope.yaml"))
    assert result.code == 1 and "config file not found" in result.err


def test_a_bug_exits_70_with_a_traceback(monkeypatch, run_cli, examples_dir: Path) -> None:
    def broken(*args, **kwargs):
        raise ZeroDivisionError("boom")

    import urdf_pipeline.execute.segment

    monkeypatch.setattr(urdf_pipeline.execute.segment, "execute", broken)
    # --force: an earlier test may have left the demo's recording up to date, and an up-to-date run computes nothing
    result = run_cli("run", str(examples_dir / "demo.yaml"), "--force")
    assert result.code == ExitCode.BUG == 70
    assert "Traceback" in result.err and "ZeroDivisionError" in result.err


def test_validate_reports_every_config(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\n")
    result = run_cli("validate", str(examples_dir / "demo.yaml"), str(bad))
    assert result.code == 1 and "ok: " in result.out and "bad.yaml:1" in result.err


def test_validate_and_plan_do_not_import_rerun(examples_dir: Path) -> None:
    demo = str(examples_dir / "demo.yaml")
    assert_commands_leave_out("rerun", ["validate", demo], ["plan", demo])


def test_run_and_validate_leave_pandas_out_and_give_it_back(examples_dir: Path) -> None:
    """pyarrow would import pandas (0.2-0.3 s) to ask whether an input is a pandas object; the commands never use it.
    After the command, pandas imports as usual (a program embedding the CLI keeps it)."""
    code = (
        "import sys; from urdf_pipeline import cli; "
        f"rc = cli.main(['run', {str(examples_dir / 'demo.yaml')!r}, '--force']); "
        f"rc |= cli.main(['validate', {str(examples_dir / 'demo.yaml')!r}]); "
        "assert rc == 0; assert 'pandas' not in sys.modules, 'pandas imported'; "
        "import pandas, pyarrow as pa; assert type(pa.table({'a': [1]}).to_pandas()).__name__ == 'DataFrame'"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_plan_shows_conversion_order_and_mimic(run_cli, examples_dir: Path) -> None:
    result = run_cli("plan", str(examples_dir / "demo.yaml"))
    assert result.code == 0
    assert "(value * unit factor * scale) * sign + offset" in result.out
    assert "mimic panda_finger_joint2 = panda_finger_joint1 * 1 + 0" in result.out


def test_module_entry_point(examples_dir: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "urdf_pipeline", "validate", str(examples_dir / "demo.yaml")], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr


def test_a_closed_pipe_is_not_a_bug(examples_dir: Path) -> None:
    """`urdf-pipeline plan CONFIG --format json | head -1`: the reader leaving early ends the command quietly."""
    command = [sys.executable, "-m", "urdf_pipeline", "plan", str(examples_dir / "bimanual_pandas.yaml"), "--format", "json"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stdout is not None and process.stderr is not None
    process.stdout.close()  # the reader is gone before the first line is written
    err = process.stderr.read()
    assert process.wait(timeout=60) == ExitCode.BROKEN_PIPE == 141
    assert "Traceback" not in err and "internal error" not in err

"""`urdf-pipeline live` and `validate --live`: what is refused before anything is subscribed."""

from __future__ import annotations

from pathlib import Path


def test_validate_live_notes_names_from_the_stream(examples_dir: Path, run_cli) -> None:
    result = run_cli("validate", "--live", str(examples_dir / "ur5_ros2_bag.yaml"))
    assert result.code == 0, result.err
    assert "note:" in result.err and "live takes them from the first message on its topic" in result.err


def test_validate_live_refuses_a_source_no_stream_carries(examples_dir: Path, run_cli) -> None:
    result = run_cli("validate", "--live", "--format", "github", str(examples_dir / "demo.yaml"))
    assert result.code == 1
    assert "::error file=" in result.out and "source 'arm_state' is a parquet source" in result.out


def test_live_refuses_before_it_connects(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    saved = tmp_path / "never.rrd"
    result = run_cli("live", str(examples_dir / "demo.yaml"), "--from", "ws://127.0.0.1:9", "--save", str(saved))
    assert result.code == 1
    lines = [line for line in result.err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "sources.arm_state: live --from streams ROS 2 JointState topics" in lines[0], result.err
    assert not saved.exists() and not list(tmp_path.iterdir())


def test_live_refuses_a_url_it_cannot_follow(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    result = run_cli("live", str(examples_dir / "ur5_ros2_bag.yaml"), "--from", "http://robot:8765", "--save", str(tmp_path / "x.rrd"))
    assert result.code == 1
    assert "error: --from: http://robot:8765: live --from takes ws://HOST:PORT" in result.err, result.err
    assert not list(tmp_path.iterdir())

"""`run --executor ray`: the same segments as Ray tasks on a local Ray instance (2 CPUs) give the same recordings."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from ..dataset_helpers import isolated_examples, recording_content, status_lines

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("allow_examples")]  # configs elsewhere read the session's examples

pytest.importorskip("ray", reason="needs Ray (a test dependency: pip install -e '.[test]')")


def test_ray_executor_writes_the_same_content_as_local_workers(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "ray")
    out = config.parent / "out" / "so101_dataset"
    local = run_cli("run", str(config), "--jobs", "2")
    assert local.code == 0, local.err
    shutil.copytree(out, tmp_path / "local")

    ray = run_cli("run", str(config), "--executor", "ray", "--jobs", "2", "--force")
    assert ray.code == 0, ray.err
    assert "2 job(s) on the ray executor" in ray.err
    assert ray.out.split() == local.out.split()
    names = sorted(p.name for p in out.glob("*.rrd"))
    assert names == ["episode_000000.rrd", "episode_000001.rrd", "episode_000002.rrd", "episode_000003.rrd", "model.rrd"]
    for name in names:
        assert recording_content(out / name) == recording_content(tmp_path / "local" / name), f"{name} differs"
    assert not list(out.glob(".*partial*"))


def test_ray_executor_reports_a_failing_segment_and_finishes_the_others(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "ray_fail")
    text = config.read_text().replace("    joints:\n", "    joints:\n      limits: {slack: 0.0, on_violation: error}\n")
    text = text.replace("        shoulder_pan: shoulder_pan\n", "        shoulder_pan: {joint: shoulder_pan, scale: 3.0}\n")
    config.write_text(text)  # tripled values leave shoulder_pan's limits in every episode
    result = run_cli("run", str(config), "--executor", "ray", "--jobs", "2", "--episodes", "0:2")
    assert result.code == 1
    assert status_lines(result.err) == {"model": "written", "episode_000000": "failed", "episode_000001": "failed"}
    assert "shoulder_pan" in result.err
    assert "Traceback" not in result.err


def test_unreachable_ray_address_is_a_user_error(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "ray_address")
    result = run_cli("run", str(config), "--executor", "ray", "--ray-address", "127.0.0.1:1", "--episodes", "0")
    assert result.code == 1 and "could not connect to the Ray cluster at 127.0.0.1:1" in result.err


def test_ray_address_comes_from_the_environment_as_ray_tools_read_it(
    examples_dir: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without --ray-address, RAY_ADDRESS names the cluster (and the run says so); --ray-address overrides it."""
    config = isolated_examples(examples_dir, tmp_path / "ray_env")
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:1")  # nothing listens there: the run must have tried it
    result = run_cli("run", str(config), "--executor", "ray", "--episodes", "0")
    assert result.code == 1, result.err
    assert "Ray: the cluster at 127.0.0.1:1 (from RAY_ADDRESS; --ray-address overrides it)" in result.err
    assert "could not connect to the Ray cluster at 127.0.0.1:1" in result.err and "Traceback" not in result.err
    overridden = run_cli("run", str(config), "--executor", "ray", "--ray-address", "127.0.0.1:2", "--episodes", "0")
    assert overridden.code == 1 and "Ray: the cluster at 127.0.0.1:2 (--ray-address)" in overridden.err
    assert "127.0.0.1:1" not in overridden.err
    local = run_cli("run", str(config), "--episodes", "0")  # the local executor never reads it
    assert local.code == 0 and "Ray" not in local.err, local.err


def test_without_an_address_a_local_instance_is_started_and_said(
    examples_dir: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    config = isolated_examples(examples_dir, tmp_path / "ray_local")
    result = run_cli("run", str(config), "--executor", "ray", "--jobs", "2", "--episodes", "0")
    assert result.code == 0, result.err
    assert "Ray: a local instance (neither --ray-address nor RAY_ADDRESS is set)" in result.err

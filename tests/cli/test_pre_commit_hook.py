"""The repository's .pre-commit-hooks.yaml, run by pre-commit itself on a fixture repository of configs.

pre-commit would build its own environment for `language: python` (a pip install, with the network); the fixture
uses the hook exactly as published (id, entry, files, types) with `language: system`, so the installed
`urdf-pipeline` runs it. The fixture is a config repository as people keep one: configs and robots in git, the
datasets elsewhere (no data folder at all), a sidecar edge file and ROS parameters beside the configs.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

REPO = Path(__file__).resolve().parents[2]
PRE_COMMIT = shutil.which("pre-commit", path=str(Path(sys.executable).parent)) or shutil.which("pre-commit")


def _git(repo: Path, *args: str) -> None:
    subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True)


@pytest.fixture
def fixture_repo(examples_dir: Path, tmp_path: Path) -> Path:
    repo = tmp_path / "robots_repo"
    (repo / "configs" / "calib").mkdir(parents=True)
    (repo / "configs" / "robots").symlink_to(examples_dir / "robots", target_is_directory=True)
    demo = yaml.safe_load((REPO / "configs" / "demo.yaml").read_text())
    (repo / "configs" / "calib" / "extrinsics.yaml").write_text(yaml.safe_dump(demo["edges"]))  # a sidecar: a list
    demo["edges"] = [{"file": "calib/extrinsics.yaml"}]
    (repo / "configs" / "demo.yaml").write_text(yaml.safe_dump(demo, sort_keys=False))
    (repo / "configs" / "controllers.yaml").write_text("controller_manager:\n  ros__parameters:\n    update_rate: 100\n")
    (repo / "notes.yaml").write_text("not: [a, config]\n")  # outside configs/: the hook leaves it alone
    (hook,) = yaml.safe_load((REPO / ".pre-commit-hooks.yaml").read_text())
    local = {**hook, "language": "system"}
    (repo / ".pre-commit-config.yaml").write_text(yaml.safe_dump({"repos": [{"repo": "local", "hooks": [local]}]}))
    _git(repo, "init", "-q")
    _git(repo, "add", "-A")
    return repo


def _run_hooks(repo: Path) -> subprocess.CompletedProcess[str]:
    assert PRE_COMMIT, "pre-commit is a test dependency"
    env = {
        **os.environ,
        "PRE_COMMIT_HOME": str(repo.parent / "pre-commit-home"),
        "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}",
    }
    return subprocess.run([PRE_COMMIT, "run", "--all-files"], cwd=repo, capture_output=True, text=True, env=env)


def test_hook_passes_valid_configs_and_fails_on_a_broken_one(fixture_repo: Path) -> None:
    assert not (fixture_repo / "configs" / "data").exists()  # the datasets live elsewhere
    passed = _run_hooks(fixture_repo)
    assert passed.returncode == 0, passed.stdout + passed.stderr
    assert "urdf-pipeline validate" in passed.stdout and "Passed" in passed.stdout

    broken = fixture_repo / "configs" / "demo.yaml"
    broken.write_text(broken.read_text().replace("j1: panda_joint1", "j1: panda_joint_1"))
    _git(fixture_repo, "add", "-A")
    failed = _run_hooks(fixture_repo)
    assert failed.returncode == 1
    assert "Failed" in failed.stdout
    assert "configs/demo.yaml:" in failed.stdout and "panda_joint_1" in failed.stdout


def test_hook_skips_what_is_not_a_config_and_reads_no_data(fixture_repo: Path) -> None:
    """The sidecar and the ROS parameters are skipped, each with its line; the config is validated without its data."""
    hook = subprocess.run(
        [
            sys.executable,
            "-m",
            "urdf_pipeline",
            *_hook_arguments(),
            "configs/calib/extrinsics.yaml",
            "configs/controllers.yaml",
            "configs/demo.yaml",
        ],
        cwd=fixture_repo,
        capture_output=True,
        text=True,
    )
    assert hook.returncode == 0, hook.stderr
    assert hook.stdout == "ok: configs/demo.yaml\n"
    assert hook.stderr.splitlines() == [
        "skipped: configs/calib/extrinsics.yaml: not a urdf-pipeline config (a top-level list, like a sidecar file of calibration edges)",
        "skipped: configs/controllers.yaml: not a urdf-pipeline config "
        "(a mapping with none of a config's top-level keys (version, sources, robots, frames, edges, trails, output, qa))",
    ]


def _hook_arguments() -> list[str]:
    """The published hook's entry, after the command's name."""
    (hook,) = yaml.safe_load((REPO / ".pre-commit-hooks.yaml").read_text())
    command, *arguments = hook["entry"].split()
    assert command == "urdf-pipeline"
    return arguments

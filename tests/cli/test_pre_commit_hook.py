"""The repository's .pre-commit-hooks.yaml, run by pre-commit itself on a fixture repository of configs.

pre-commit would build its own environment for `language: python` (a pip install, with the network); the fixture
uses the hook exactly as published (id, entry, files, types) with `language: system`, so the installed
`urdf-pipeline` runs it.
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
    (repo / "configs").mkdir(parents=True)
    for folder in ("robots", "data"):
        (repo / "configs" / folder).symlink_to(examples_dir / folder, target_is_directory=True)
    shutil.copy(REPO / "configs" / "demo.yaml", repo / "configs" / "demo.yaml")
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

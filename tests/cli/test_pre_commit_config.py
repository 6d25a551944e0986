"""The contributors' `.pre-commit-config.yaml` is valid and its hooks pass on this checkout, as `make lint` does."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_the_contributor_hooks_pass_on_this_checkout(tmp_path: Path) -> None:
    if not (ROOT / ".venv" / "bin" / "mypy").exists() or not (ROOT / ".git").exists():
        pytest.skip("the hooks run the tools of this checkout's .venv (make test creates it) in a git checkout")
    if shutil.which("git") is None:
        pytest.skip("pre-commit needs git")
    env = {**os.environ, "PRE_COMMIT_HOME": str(tmp_path / "pre-commit-home")}
    command = [sys.executable, "-m", "pre_commit"]
    checked = subprocess.run([*command, "validate-config", ".pre-commit-config.yaml"], cwd=ROOT, env=env, capture_output=True, text=True)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    ran = subprocess.run([*command, "run", "--all-files"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert ran.returncode == 0, ran.stdout + ran.stderr
    for hook in ("ruff check", "ruff format", "mypy", "urdf-pipeline validate --no-data", "config package tests"):
        assert hook in ran.stdout, ran.stdout

"""docs/ci.md's GitHub Actions workflows: valid YAML, included verbatim, safe for fork pull requests, every urdf-pipeline
command in them one the CLI accepts, and the review script run for real on a git repository with a base and a PR branch."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from urdf_pipeline.cli import build_parser

REPO = Path(__file__).resolve().parents[2]
WORKFLOWS = REPO / "docs" / "workflows"
REVIEW = WORKFLOWS / "robot-configs.yml"
COMMENT = WORKFLOWS / "robot-configs-comment.yml"
MARKER = "<!-- urdf-pipeline-review -->"


def _load(path: Path) -> dict[Any, Any]:
    data: dict[Any, Any] = yaml.safe_load(path.read_text())
    data["on"] = data.pop(True, data.get("on"))  # YAML 1.1 reads the key `on` as True
    return data


def _steps(path: Path, job: str) -> list[dict[str, Any]]:
    steps: list[dict[str, Any]] = _load(path)["jobs"][job]["steps"]
    return steps


def _commands() -> list[list[str]]:
    found = []
    for step in _steps(REVIEW, "review"):
        for line in str(step.get("run", "")).splitlines():
            for match in re.finditer(
                r"(?<![\w\"])urdf-pipeline ((?:validate|plan|diff|run|check|init|schema)\b[^|;&]*?)(?:\s*2>&1)?(?:\s*\|\||\s*;|$)", line
            ):
                words = shlex.split(
                    match.group(1).replace('"$config"', "c.yaml").replace('"$base"', "origin/main").replace("$CONFIGS", "c.yaml")
                )
                found.append(words)
    return found


def test_workflows_are_in_the_docs_verbatim() -> None:
    docs = (REPO / "docs" / "ci.md").read_text()
    assert REVIEW.read_text() in docs
    assert COMMENT.read_text() in docs


def test_every_command_of_the_workflow_parses() -> None:
    commands = _commands()
    assert {c[0] for c in commands} >= {"validate", "diff", "plan"}
    for words in commands:
        build_parser().parse_args(words)  # SystemExit (exit 2) on an unknown subcommand or option


def test_pr_workflow_reads_pr_content_with_a_read_only_token() -> None:
    review = _load(REVIEW)
    assert list(review["on"]) == ["pull_request"], "PR content must not be read under pull_request_target or workflow_run"
    assert review["permissions"] == {"contents": "read"}
    checkout = next(s for s in _steps(REVIEW, "review") if str(s.get("uses", "")).startswith("actions/checkout"))
    assert checkout["with"]["persist-credentials"] is False
    setup = next(s for s in _steps(REVIEW, "review") if str(s.get("uses", "")).startswith("actions/setup-python"))
    assert setup["with"]["cache"] == "pip"
    runs = "\n".join(str(s.get("run", "")) for s in _steps(REVIEW, "review"))
    assert "pip install ." not in runs and "pip install -e" not in runs, "the PR's own checkout must not be installed"
    text = REVIEW.read_text()
    assert "...HEAD" in text, "changed configs come from a three-dot diff against the merge base"
    assert "${{ github.event.pull_request.title" not in text and "${{ github.head_ref" not in text


def test_comment_workflow_never_runs_pr_code() -> None:
    comment = _load(COMMENT)
    assert list(comment["on"]) == ["workflow_run"]
    assert comment["permissions"] == {"actions": "read", "pull-requests": "write"}
    steps = _steps(COMMENT, "comment")
    assert not any(str(s.get("uses", "")).startswith("actions/checkout") for s in steps), "no checkout in the commenting job"
    text = COMMENT.read_text()
    assert "urdf-pipeline " not in text.replace("urdf-pipeline-review", "")
    assert "--edit-last" not in text, "edit the comment carrying our marker, not the bot's last comment"
    assert MARKER in text


@pytest.mark.skipif(shutil.which("git") is None or shutil.which("bash") is None, reason="needs git and bash")
def test_review_script_runs_on_a_pull_request_branch(examples_dir: Path, tmp_path: Path) -> None:
    """The `plan and diff` step, run by bash in a clone whose PR branch changed one config: one section for it, with
    the diff against the merge base (not against a base branch that moved on) and the plan."""
    origin = tmp_path / "origin"
    shutil.copytree(examples_dir, origin, symlinks=True, ignore=shutil.ignore_patterns("out", "invalid_*"))
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@example.com", "-c", "init.defaultBranch=main"]
    subprocess.run([*git, "init", "-q"], cwd=origin, check=True)
    subprocess.run([*git, "add", "-A"], cwd=origin, check=True)
    subprocess.run([*git, "commit", "-qm", "base"], cwd=origin, check=True)
    work = tmp_path / "work"
    subprocess.run([*git, "clone", "-q", str(origin), str(work)], check=True)
    for name in ("robots", "data"):  # generated inputs are not committed in real repositories either: link them
        if not (work / name).exists():
            (work / name).symlink_to(examples_dir / name)
    subprocess.run([*git, "checkout", "-qb", "pr"], cwd=work, check=True)
    demo = work / "demo.yaml"
    demo.write_text(demo.read_text().replace("translation: [0.0, 0.0, 0.5]", "translation: [0.0, 0.0, 0.505]"))
    subprocess.run([*git, "commit", "-qam", "raise the arm 5 mm"], cwd=work, check=True)
    # The base branch moves on after the PR branched: its change must not show in the PR's review.
    (origin / "bimanual_pandas.yaml").write_text((origin / "bimanual_pandas.yaml").read_text() + "# later on main\n")
    subprocess.run([*git, "commit", "-qam", "later"], cwd=origin, check=True)
    subprocess.run([*git, "fetch", "-q", "origin"], cwd=work, check=True)

    step = next(s for s in _steps(REVIEW, "review") if s.get("name") == "plan and diff of each changed config")
    bin_dir = str(Path(sys.executable).parent)
    env = {**os.environ, "CONFIGS": "*.yaml", "BASE_REF": "main", "PR_NUMBER": "7", "PATH": bin_dir + os.pathsep + os.environ["PATH"]}
    result = subprocess.run(["bash", "-eo", "pipefail", "-c", step["run"]], cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr

    body = (work / "review" / "comment.md").read_text()
    assert (work / "review" / "pr-number").read_text().strip() == "7"
    assert body.startswith(MARKER)
    assert "#### `demo.yaml`" in body
    assert "bimanual_pandas.yaml" not in body, "a change on the base branch showed up in the PR's review"
    assert "moved 5.0 mm" in body, body
    assert "### urdf-pipeline plan: `demo.yaml`" in body
    pictures = work / "review" / "pictures" / "demo"
    if pictures.is_dir():  # drawn (a renderer is there): linked by the paths the artifact holds them at
        for name in ("demo.diff.old.png", "demo.diff.new.png", "demo.diff.png", "demo.plan.scene.png"):
            assert f"(review/pictures/demo/{name})" in body and (pictures / name).is_file(), name
    else:  # no renderer: one line says what to install, and the text comes without pictures
        assert "apt-get install mesa-vulkan-drivers" in body

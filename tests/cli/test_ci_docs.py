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
from urdf_pipeline.web import ViewerAssets

from ..web.conftest import viewer_cache  # noqa: F401 (the sites take the viewer from the session's cache)

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


def _runs(path: Path, job: str) -> str:
    return "\n".join(str(step.get("run", "")) for step in _steps(path, job))


PLACEHOLDERS = {
    '"$config"': "c.yaml",
    '"$base"': "origin/main",
    "$CONFIGS": "c.yaml",
    '"../site/$n"': "site/1",
    '"../pictures/$n"': "pictures/1",
}


def _commands() -> list[list[str]]:
    """Every urdf-pipeline command line of the review job and of the site job, with its shell variables filled in."""
    found = []
    for line in (_runs(REVIEW, "review") + "\n" + _runs(COMMENT, "site")).splitlines():
        for match in re.finditer(
            r"(?<![\w\"])urdf-pipeline ((?:validate|plan|diff|run|check|init|schema)\b[^|;&]*?)(?:\s*>\s*/dev/null)?(?:\s*2>&1)?(?:\s*\|\||\s*;|$)",
            line,
        ):
            text = match.group(1)
            for variable, value in PLACEHOLDERS.items():
                text = text.replace(variable, value)
            found.append(shlex.split(text))
    return found


def test_workflows_are_in_the_docs_verbatim() -> None:
    docs = (REPO / "docs" / "ci.md").read_text()
    assert REVIEW.read_text() in docs
    assert COMMENT.read_text() in docs


def test_every_command_of_the_workflow_parses() -> None:
    commands = _commands()
    assert {c[0] for c in commands} >= {"validate", "diff", "plan"}
    assert sum("--html" in c for c in commands) == 3  # the site job: diff with pictures, diff, plan of a new config
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
    """workflow_run: this file as the default branch has it. The site job reads the PR's files as data with a
    read-only token and the pinned release; the comment job holds the write permissions and reads no PR file."""
    comment = _load(COMMENT)
    assert list(comment["on"]) == ["workflow_run"]
    assert comment["permissions"] == {}
    jobs = comment["jobs"]
    assert jobs["site"]["permissions"] == {"contents": "read", "actions": "read", "pull-requests": "read"}
    assert jobs["comment"]["permissions"] == {"actions": "read", "contents": "write", "pull-requests": "write"}
    text = COMMENT.read_text()
    assert "--edit-last" not in text, "edit the comment carrying our marker, not the bot's last comment"
    assert MARKER in text

    steps = _steps(COMMENT, "comment")
    checkouts = [s for s in steps if str(s.get("uses", "")).startswith("actions/checkout")]
    assert [c["with"]["ref"] for c in checkouts] == ["gh-pages"], "the comment job checks out only this repository's pages"
    assert not re.search(r"urdf-pipeline (validate|plan|diff|run|check|init|schema|snapshot|browse)\b", _runs(COMMENT, "comment"))
    assert "pip install" not in _runs(COMMENT, "comment")

    steps = _steps(COMMENT, "site")
    uses = [str(s.get("uses", "")) for s in steps]
    setup = steps[uses.index("actions/setup-python@v5")]
    assert "cache" not in setup["with"], "no cache written by a workflow_run job (it is shared with the default branch)"
    install = next(i for i, s in enumerate(steps) if "pip install" in str(s.get("run", "")))
    checkout = uses.index("actions/checkout@v4")
    assert install < checkout, "the pinned release is installed before any PR file is on disk"
    assert "pip install ." not in _runs(COMMENT, "site") and "pip install -e" not in _runs(COMMENT, "site")
    assert steps[checkout]["with"]["persist-credentials"] is False
    assert steps[checkout]["with"]["ref"] == "refs/pull/${{ steps.pr.outputs.number }}/head"
    assert 'git rev-parse HEAD)" = "$HEAD_SHA"' in steps[checkout + 1]["run"], "the checkout must be the run's head"


def _pr_clone(examples_dir: Path, tmp_path: Path) -> Path:
    """A clone whose branch `pr` raised demo.yaml's arm by 5 mm, while main moved on after it branched."""
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
    return work


def _run_step(path: Path, job: str, name: str, cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    step = next(s for s in _steps(path, job) if s.get("name") == name)
    bin_dir = str(Path(sys.executable).parent)
    environment = {**os.environ, "CONFIGS": "*.yaml", "PATH": bin_dir + os.pathsep + os.environ["PATH"], **env}
    return subprocess.run(
        ["bash", "-eo", "pipefail", "-c", step["run"]], cwd=cwd, env=environment, capture_output=True, text=True, timeout=300
    )


@pytest.mark.skipif(shutil.which("git") is None or shutil.which("bash") is None, reason="needs git and bash")
def test_review_script_runs_on_a_pull_request_branch(examples_dir: Path, tmp_path: Path) -> None:
    """The `plan and diff` step, run by bash in a clone whose PR branch changed one config: one section for it, with
    the diff against the merge base (not against a base branch that moved on) and the plan."""
    work = _pr_clone(examples_dir, tmp_path)
    result = _run_step(REVIEW, "review", "plan and diff of each changed config", work, BASE_REF="main", PR_NUMBER="7")
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


@pytest.mark.skipif(
    shutil.which("git") is None or shutil.which("bash") is None or shutil.which("find") is None, reason="needs git, bash, find"
)
def test_site_steps_build_the_sites_and_publish_only_sites(examples_dir: Path, tmp_path: Path, viewer_cache: ViewerAssets) -> None:  # noqa: F811
    """The site job's build step, by bash in a clone of a PR branch (as the job checks it out): one site for the
    changed config, with old and new; then the comment job's check accepts it, and refuses it once anything is in it
    that plan --html and diff --html do not write."""
    work = _pr_clone(examples_dir, tmp_path)
    built = _run_step(COMMENT, "site", "the review sites of the changed configs", work, BASE_REF="main")
    assert built.returncode == 0, built.stderr
    site = tmp_path / "site"
    assert sorted(p.name for p in site.iterdir()) == ["1", "1.name"] and (site / "1.name").read_text() == "demo.yaml"
    page = (site / "1" / "index.html").read_text()
    assert "moved 5.0 mm" in page and "bimanual" not in page  # the PR's change, not main's later one
    assert {"old.rrd", "new.rrd", "old.rbl", "new.rbl"} <= {p.name for p in (site / "1" / "recordings").iterdir()}

    def check() -> str:
        output = tmp_path / "github-output"
        output.write_text("")
        result = _run_step(COMMENT, "comment", "check the sites", tmp_path, GITHUB_OUTPUT=str(output))
        assert result.returncode == 0, result.stderr
        return output.read_text().strip()

    assert check() == "sites=ok"
    for tamper in ("script", "file", "link"):
        backup = tmp_path / "backup"
        shutil.copytree(site, backup, symlinks=True)
        if tamper == "script":
            (site / "1" / "index.html").write_text(page.replace("</main>", '<SCRIPT src="viewer/boot.js"></SCRIPT></main>'))
        elif tamper == "file":
            (site / "1" / "viewer" / "evil.js").write_text("alert(1)")
        else:
            (site / "1" / "recordings" / "rest_pose.rrd").symlink_to("/etc/passwd")
        assert check() == "sites=refused", tamper
        shutil.rmtree(site)
        backup.rename(site)
    shutil.rmtree(site)
    assert check() == "sites=none"

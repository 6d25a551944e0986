"""docs/ci.md's GitHub Actions workflow: valid YAML, included verbatim, and every urdf-pipeline command in it is one the CLI accepts."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import yaml

from urdf_pipeline.cli import build_parser

REPO = Path(__file__).resolve().parents[1]
WORKFLOW = REPO / "docs" / "workflows" / "robot-configs.yml"


def _commands() -> list[list[str]]:
    steps = yaml.safe_load(WORKFLOW.read_text())["jobs"]["review"]["steps"]
    found = []
    for step in steps:
        for line in str(step.get("run", "")).splitlines():
            for match in re.finditer(
                r"(?<![\w\"])urdf-pipeline ((?:validate|plan|diff|run|check|init|schema)\b[^|;&]*?)(?:\s*\|\||\s*;|$)", line
            ):
                words = shlex.split(
                    match.group(1).replace('"$config"', "c.yaml").replace('"$base"', "origin/main").replace("$CONFIGS", "c.yaml")
                )
                found.append(words)
    return found


def test_workflow_is_in_the_docs_verbatim() -> None:
    assert WORKFLOW.read_text() in (REPO / "docs" / "ci.md").read_text()


def test_every_command_of_the_workflow_parses() -> None:
    commands = _commands()
    assert {c[0] for c in commands} >= {"validate", "diff", "plan"}
    for words in commands:
        build_parser().parse_args(words)  # SystemExit (exit 2) on an unknown subcommand or option

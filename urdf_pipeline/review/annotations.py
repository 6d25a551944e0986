"""`validate --format github|json`: every problem of every config as one record, for CI and review tools.

`github` renders each record as a GitHub Actions workflow command (`::error file=F,line=L,col=C::PATH: message`), so
the problems show as annotations on the pull request's files; `json` as a list of objects. Records are sorted by file,
line, column, YAML path, severity (errors first) and message, and identical ones (a sidecar shared by two configs)
appear once. Line and column are 1-based, 0 when unknown (a problem with the file as a whole).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

from ..errors import ConfigWarning, UserError, UserErrors, Where, collect_warnings

Severity = Literal["error", "warning"]


@dataclass(frozen=True)
class Annotation:
    file: str  # as the user gave it (relative stays relative), normalized: `./a/../b.yaml` -> `b.yaml`
    line: int
    column: int
    path: str  # the YAML path, `robots.arm.joints.map.j1`; "" when none
    severity: Severity
    message: str

    @staticmethod
    def at(severity: Severity, message: str, where: Where | None, config: str) -> Annotation:
        """A problem at `where`; one without a place is put on the config being validated, as a whole."""
        if where is None:
            return Annotation(os.path.normpath(config), 0, 0, "", severity, message)
        return Annotation(os.path.normpath(where.file), where.line, where.column if where.line else 0, where.path, severity, message)

    def sort_key(self) -> tuple[str, int, int, str, int, str]:
        return self.file, self.line, self.column, self.path, 0 if self.severity == "error" else 1, self.message

    def github(self) -> str:
        """The workflow command: `::error file=F,line=L,col=C::PATH: message` (line and col only when known)."""
        properties = [f"file={_escape_property(self.file)}"]
        if self.line:
            properties.append(f"line={self.line}")
            if self.column:
                properties.append(f"col={self.column}")
        text = f"{self.path}: {self.message}" if self.path else self.message
        return f"::{self.severity} {','.join(properties)}::{_escape_data(text)}"


@dataclass
class Findings:
    """What validating several configs found: every annotation, and which configs compiled."""

    annotations: list[Annotation] = field(default_factory=list)
    valid: list[str] = field(default_factory=list)
    invalid: list[str] = field(default_factory=list)

    def sorted(self) -> list[Annotation]:
        return sorted(dict.fromkeys(self.annotations), key=Annotation.sort_key)


def validate_configs(configs: Sequence[str]) -> Findings:
    """Compile every config as `validate` does, collecting its errors and warnings instead of printing them."""
    from ..compile.compiler import compile_config

    findings = Findings()
    for config in configs:
        errors: list[UserError] = []
        warnings: list[ConfigWarning]
        with collect_warnings() as warnings:
            try:
                compile_config(Path(config))
            except UserError as exc:
                errors = exc.errors if isinstance(exc, UserErrors) else [exc]
        findings.annotations += [Annotation.at("warning", w.message, w.where, config) for w in warnings]
        findings.annotations += [Annotation.at("error", e.message, e.where, config) for e in errors]
        (findings.invalid if errors else findings.valid).append(config)
    return findings


def render(annotations: Sequence[Annotation], format: Literal["github", "json"]) -> str:
    """The text for stdout: one workflow command a line, or a JSON list (`[]` when there is nothing to say)."""
    if format == "github":
        return "".join(annotation.github() + "\n" for annotation in annotations)
    return json.dumps([asdict(annotation) for annotation in annotations], indent=2) + "\n"


def _escape_data(text: str) -> str:
    """GitHub's escaping of a workflow command's message."""
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _escape_property(text: str) -> str:
    """GitHub's escaping of a workflow command's property value: the message's, plus `:` and `,`."""
    return _escape_data(text).replace(":", "%3A").replace(",", "%2C")

"""`validate`: what validating each config found (ConfigResult), and its text, github and json renderings (their
forms: docs/commands.md#validate). github and json sort the records and print identical ones (a sidecar shared by two
configs) once."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

from ...errors import LINE_LIMIT, ConfigWarning, UserError, UserErrors, Where, collect_warnings, located, neutral_line, shortened, shown
from .non_config import not_a_config

Severity = Literal["error", "warning", "note"]
PART = LINE_LIMIT // 8  # characters of an annotation's file or YAML path (the message has LINE_LIMIT // 2)
SEVERITY_ORDER = {"error": 0, "warning": 1, "note": 2}
GITHUB_COMMAND = {"error": "error", "warning": "warning", "note": "notice"}
AnnotationFormat = Literal["github", "json"]


@dataclass(frozen=True)
class Problem:
    """One error, warning or note of a config, at its place (None: the config as a whole)."""

    severity: Severity
    message: str
    where: Where | None

    def line(self) -> str:
        """The text form: `error: FILE:LINE:COL: YAML.PATH: message`, the file as the config names it."""
        return located(self.severity, self.message, self.where)


@dataclass(frozen=True)
class ConfigResult:
    """What validating one config found: the model every format of `validate` renders."""

    config: str  # as the user gave it
    warnings: tuple[Problem, ...]  # in the order compiling raised them
    errors: tuple[Problem, ...]
    notes: tuple[Problem, ...] = ()  # --no-data: what only the data could check
    skipped: str = ""  # --skip-non-configs: why the file is not a config (then nothing else is set)

    @property
    def ok(self) -> bool:
        """No error: the exit status. A skipped file has none."""
        return not self.errors

    def ok_line(self) -> str:
        return neutral_line(f"ok: {self.config}") + "\n" if self.ok and not self.skipped else ""

    def annotations(self) -> list[Annotation]:
        return [Annotation.at(p.severity, p.message, p.where, self.config) for p in (*self.warnings, *self.errors, *self.notes)]

    def skipped_line(self) -> str:
        return neutral_line(f"skipped: {self.config}: not a urdf-pipeline config ({self.skipped})") + "\n" if self.skipped else ""


@dataclass(frozen=True)
class Annotation:
    """A problem as CI sees it (github, json): the file normalised, line and column 0 when unknown. Its texts come
    from the pull request (file names, YAML keys, URDF names in messages): each is held as `errors.shown` gives it,
    one line, control characters visible, bounded, so neither format carries a raw newline, ESC or a megabyte."""

    file: str  # as the user gave it (relative stays relative), normalized: `./a/../b.yaml` -> `b.yaml`
    line: int
    column: int
    path: str  # the YAML path, `robots.arm.joints.map.j1`; "" when none
    severity: Severity
    message: str

    @staticmethod
    def at(severity: Severity, message: str, where: Where | None, config: str) -> Annotation:
        """A problem at `where`; one without a place is put on the config being validated, as a whole."""
        text = shown(message, LINE_LIMIT // 2)
        if where is None:
            return Annotation(shown(os.path.normpath(config), PART), 0, 0, "", severity, text)
        file, path = shown(os.path.normpath(where.file), PART), shown(where.path, PART)
        return Annotation(file, where.line, where.column if where.line else 0, path, severity, text)

    def sort_key(self) -> tuple[str, int, int, str, int, str]:
        return self.file, self.line, self.column, self.path, SEVERITY_ORDER[self.severity], self.message

    def github(self) -> str:
        """The workflow command: `::error file=F,line=L,col=C::PATH: message` (line and col only when known), escaped
        as GitHub reads them: `%`, CR and LF in the message; `%`, CR, LF, `:` and `,` in a property."""
        properties = [f"file={_escape_property(self.file)}"]
        if self.line:
            properties.append(f"line={self.line}")
            if self.column:
                properties.append(f"col={self.column}")
        head = f"::{GITHUB_COMMAND[self.severity]} {','.join(properties)}::"
        text = f"{self.path}: {self.message}" if self.path else self.message
        data = _escape_data(text)
        if len(head) + len(data) > LINE_LIMIT:  # each `%` takes three characters escaped: the line stays bounded
            data = _escape_data(shortened(text, (LINE_LIMIT - len(head)) // 3))
        return head + data


def validate_config(config: str, *, data: bool = True, skip_non_configs: bool = False, live: bool = False) -> ConfigResult:
    """Compile the config as `validate` does, collecting its errors and warnings instead of printing them. `data` False
    (`--no-data`) and `live` (`--live`) open no source file (their checks: docs/commands.md#validate);
    `skip_non_configs`: a YAML file that is no config (non_config.py) is skipped rather than refused."""
    from ...compile import FROM_CONFIG, FROM_STREAM, check_config, compile_config

    if skip_non_configs:
        reason = not_a_config(Path(config))
        if reason is not None:
            return ConfigResult(config, (), (), skipped=reason)
    errors: list[UserError] = []
    notes: tuple[Problem, ...] = ()
    warnings: list[ConfigWarning]
    with collect_warnings() as warnings:
        try:  # one catch for both paths: a check that raises instead of collecting is a problem of this config too
            if data and not live:
                compile_config(Path(config))
            else:
                found = check_config(Path(config), FROM_STREAM if live else FROM_CONFIG)
                errors = list(found.errors)
                notes = tuple(Problem("note", note.message, note.where) for note in found.notes)
        except UserError as exc:
            errors = exc.errors if isinstance(exc, UserErrors) else [exc]
    return ConfigResult(
        config,
        tuple(Problem("warning", w.message, w.where) for w in warnings),
        tuple(Problem("error", e.message, e.where) for e in errors),
        notes,
    )


@dataclass(frozen=True)
class Shown:
    """What one rendering prints: on stdout, and on stderr."""

    stdout: str
    stderr: str


def render_text_progress(result: ConfigResult) -> Shown:
    """text, as each config is done: its warnings and notes (or why it was skipped), and `ok: CONFIG` when it has no
    error."""
    said = result.skipped_line() + "".join(p.line() + "\n" for p in (*result.warnings, *result.notes))
    return Shown(result.ok_line(), said)


def render_text_errors(results: Iterable[ConfigResult]) -> str:
    """text, once every config is done: every error of every config, in order (for stderr)."""
    return "".join(p.line() + "\n" for result in results for p in result.errors)


def render_annotations(results: Sequence[ConfigResult], format: AnnotationFormat) -> Shown:
    """github / json: the annotations on stdout (one workflow command a line, or a JSON list, `[]` when there is
    nothing to say), `ok: CONFIG` and the skipped files on stderr."""
    annotations = sorted(dict.fromkeys(a for result in results for a in result.annotations()), key=Annotation.sort_key)
    if format == "github":
        stdout = "".join(annotation.github() + "\n" for annotation in annotations)
    else:
        stdout = json.dumps([asdict(annotation) for annotation in annotations], indent=2) + "\n"
    return Shown(stdout, "".join(result.ok_line() + result.skipped_line() for result in results))


def _escape_data(text: str) -> str:
    """GitHub's escaping of a workflow command's message."""
    return text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")


def _escape_property(text: str) -> str:
    """GitHub's escaping of a workflow command's property value: the message's, plus `:` and `,`."""
    return _escape_data(text).replace(":", "%3A").replace(",", "%2C")

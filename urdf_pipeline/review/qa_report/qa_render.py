"""`qa`'s report: its text, json, markdown and github forms, each rendered from the one record form the data pass
gives (`QaReport.as_data`, docs/qa.md), and the `--fail-on` gate. Every string from the data (segment ids, joint
names) goes out through `errors.shown` (text), the Markdown helpers (markdown) or the annotation's escaping (github)."""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal

from ...errors import UserError, did_you_mean, listing, quoted, shown
from ...plan import QA_FLAGS, QaFlag
from ..markdown_text import cell, code, plain
from ..validate.annotations import Annotation

QaFormat = Literal["text", "json", "github", "markdown"]


def render_qa(data: Mapping[str, Any], form: QaFormat, config: str) -> str:
    """The report in `form`; `config` is the file the github annotations are put on."""
    if form == "json":
        return json.dumps(data, indent=2) + "\n"
    if form == "markdown":
        return _markdown(data)
    if form == "github":
        return "".join(_annotation(segment, config) + "\n" for segment in data["segments"] if segment["flags"])
    return _text(data)


def _duration(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds:.3f} s"


def _flags(flags: Sequence[str]) -> str:
    return ", ".join(flags) if flags else "ok"


def _summary(data: Mapping[str, Any]) -> str:
    summary = data["summary"]
    counts = ", ".join(f"{flag} {count}" for flag, count in summary["by_flag"].items())
    return f"{summary['flagged']} of {summary['segments']} segment(s) flagged" + (f" ({counts})" if counts else "")


def _text(data: Mapping[str, Any]) -> str:
    lines = [f"{shown(s['id'])}: {s['rows']:,} rows, {_duration(s['duration_s'])}, {_flags(s['flags'])}" for s in data["segments"]]
    return "".join(line + "\n" for line in [*lines, _summary(data)])


def _markdown(data: Mapping[str, Any]) -> str:
    lines = ["## Dataset QA", "", plain(_summary(data)), "", "| segment | rows | duration | flags | worst joint (max jerk p95) |"]
    lines.append("| --- | ---: | ---: | --- | --- |")
    for segment in data["segments"]:
        jerks = {name: joint["p95_abs_jerk"] for name, joint in segment["joints"].items() if joint["p95_abs_jerk"] is not None}
        worst = max(jerks, key=lambda name: jerks[name]) if jerks else None
        joint = "-" if worst is None else f"{code(worst)} {jerks[worst]:.3g}"
        row = [code(segment["id"]), f"{segment['rows']:,}", _duration(segment["duration_s"]), plain(_flags(segment["flags"])), joint]
        lines.append("| " + " | ".join(cell(part) for part in row) + " |")
    return "\n".join(lines) + "\n"


def _annotation(segment: Mapping[str, Any], config: str) -> str:
    """One `::warning` per flagged segment, on the config, escaped as validate's annotations are."""
    message = f"segment {quoted(segment['id'])}: {_flags(segment['flags'])}"
    return Annotation.at("warning", message, None, config).github()


def fail_on_flags(text: str | None, configured: Iterable[QaFlag]) -> tuple[QaFlag, ...]:
    """`--fail-on a,b` checked against QA_FLAGS; the config's `qa.fail_on` when the option is absent."""
    if text is None:
        return tuple(configured)
    found: list[QaFlag] = []
    for name in (part.strip() for part in text.split(",")):
        if not name:
            continue
        if name not in QA_FLAGS:
            raise UserError(f"--fail-on: unknown flag {quoted(name)}{did_you_mean(name, QA_FLAGS)}; flags are {listing(QA_FLAGS)}")
        found.append(next(flag for flag in QA_FLAGS if flag == name))
    return tuple(found)


def failure(data: Mapping[str, Any], fail_on: Sequence[QaFlag]) -> UserError | None:
    """The one error line naming the segments that raised a flag of `fail_on`, and those flags; None when none did."""
    failing = [(s["id"], [f for f in s["flags"] if f in fail_on]) for s in data["segments"]]
    named = [f"{quoted(segment)} ({', '.join(flags)})" for segment, flags in failing if flags]
    if not named:
        return None
    return UserError(f"qa: {len(named)} segment(s) raised a --fail-on flag: {listing(named)}")

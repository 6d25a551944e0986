"""Expand a xacro file from an untrusted config in a bounded child process (the sandbox is xacro_sandbox; what the child
may do: docs/security.md, Code), killed when the wall clock runs out. Every way it can fail ends in a UserError naming
the xacro file.

The wall clock is one budget per config (`XacroBudget`), so ten robots naming a slow xacro cannot take ten times the
bound. An expansion is reused while every file xacro read (and what each include pattern matched) is unchanged.
"""

from __future__ import annotations

import glob
import hashlib
import os
import stat
import sys
import time
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..confine import Confinement
from ..errors import UserError, Where, listing, neutral_text, shown
from ..process import ChildOutcome, bound_from_environment, passed_environment, run_bounded_child, sandboxed_python
from .xml_text import MAX_URDF_BYTES

MEMORY_ENV = "URDF_PIPELINE_XACRO_MEMORY_MB"  # the runner may raise the bounds for a huge robot; a config cannot
TIMEOUT_ENV = "URDF_PIPELINE_XACRO_TIMEOUT"
DEFAULT_MEMORY_MB = 1024
DEFAULT_TIMEOUT_S = 60.0
OUTPUT_BYTES = MAX_URDF_BYTES  # the expanded URDF text, at most: what any URDF text may be
ANSWER_BYTES = OUTPUT_BYTES + (1 << 20)  # the child's whole answer: the text and the files it read
SHOWN_STDERR = 16 << 10  # xacro's own warnings passed on, at most
_PASSED_ENV = ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH", "LD_LIBRARY_PATH", "DYLD_LIBRARY_PATH", "SYSTEMROOT")
CACHED_BYTES = 256 << 20  # expanded texts kept for reuse, at most
SMALLEST_SLICE_S = 0.05  # an expansion the budget has less time left for is not started
_HASHED_CHUNK = 1 << 20


@dataclass(frozen=True)
class XacroRequest:
    file: Path  # resolved, already allowed by the confinement
    shown: str  # as the config writes it
    args: Mapping[str, str]
    package_paths: Mapping[str, Path]
    confinement: Confinement


@dataclass(frozen=True)
class Limits:
    memory_mb: int
    timeout_s: float

    @staticmethod
    def from_environment(where: Where | None) -> Limits:
        return Limits(
            int(bound_from_environment(MEMORY_ENV, DEFAULT_MEMORY_MB, where)), bound_from_environment(TIMEOUT_ENV, DEFAULT_TIMEOUT_S, where)
        )


@dataclass
class XacroBudget:
    """The wall-clock seconds all xacro expansions of one config (or of one init command) share: URDF_PIPELINE_XACRO_TIMEOUT,
    read at the first expansion. `owner` names the budget in messages ("this config's")."""

    owner: str = "this config's"
    seconds: float | None = None
    spent: float = 0.0
    spenders: list[str] = field(default_factory=list)  # the expansions that took time from it, as the config names them
    shown: set[tuple[Any, ...]] = field(default_factory=set)  # expansions whose xacro warnings this budget passed on

    def left(self, limits: Limits) -> float:
        if self.seconds is None:
            self.seconds = limits.timeout_s
        return self.seconds - self.spent

    def charge(self, seconds: float, shown: str) -> None:
        self.spent += seconds
        self.spenders.append(shown)

    def exhausted(self, request: XacroRequest) -> str:
        return (
            f"xacro expansion of {request.shown} was not started: {self.owner} xacro time budget of {self.seconds:g} s was used "
            f"up by the expansions before it ({listing(self.spenders)}); expand fewer or faster xacro files (a xacro named "
            f"again with the same args is expanded once), or the person running the tool can raise the budget with {TIMEOUT_ENV}"
        )


@dataclass(frozen=True)
class _Expansion:
    """A successful expansion, kept while every file it read holds the same bytes."""

    text: str
    files: tuple[tuple[str, str], ...]  # (absolute path, sha256) of every file xacro read
    globs: tuple[tuple[str, tuple[str, ...]], ...]  # (absolute include pattern, the files it matched, sorted)
    warnings: bytes  # what xacro printed on stderr, at most SHOWN_STDERR + 1 bytes

    def unchanged(self) -> bool:
        return all(_sha256(Path(file)) == digest for file, digest in self.files) and all(
            tuple(sorted(glob.glob(pattern))) == matches for pattern, matches in self.globs
        )


_EXPANSIONS: OrderedDict[tuple[Any, ...], _Expansion] = OrderedDict()  # oldest first


def _sha256(path: Path) -> str | None:
    """The file's sha256; None when it is not a regular file (a FIFO would block) or cannot be read."""
    digest = hashlib.sha256()
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            return None
        with path.open("rb") as file:
            while chunk := file.read(_HASHED_CHUNK):
                digest.update(chunk)
    except OSError:
        return None
    return digest.hexdigest()


def _key(request: XacroRequest) -> tuple[Any, ...] | None:
    """What an expansion depends on besides the files it includes; None when the xacro file cannot be read here."""
    digest = _sha256(request.file)
    if digest is None:
        return None
    return (
        str(request.file),
        digest,
        tuple(sorted(request.args.items())),
        tuple(sorted((name, str(path)) for name, path in request.package_paths.items())),
        str(request.confinement.config_dir),
        tuple(str(root) for root in request.confinement.read_roots),
        tuple(os.environ.get(name) for name in _PASSED_ENV),
    )


def _remember(key: tuple[Any, ...], answer: Mapping[str, Any], warnings: bytes) -> None:
    files = tuple((str(file), _sha256(Path(file)) or "") for file in answer.get("files", ()))
    globs = tuple((str(pattern), tuple(sorted(map(str, matches)))) for pattern, matches in answer.get("globs", ()))
    _EXPANSIONS[key] = _Expansion(str(answer["text"]), files, globs, warnings)
    while sum(len(kept.text) for kept in _EXPANSIONS.values()) > CACHED_BYTES and len(_EXPANSIONS) > 1:
        _EXPANSIONS.popitem(last=False)


def expand_xacro(request: XacroRequest, where: Where | None, budget: XacroBudget | None = None) -> str:
    """The URDF text of `request.file` expanded with its args, or a UserError at `where` naming the xacro file. The time
    comes from `budget` (a budget of its own when None); a text expanded before from unchanged files is reused."""
    limits = Limits.from_environment(where)
    budget = budget if budget is not None else XacroBudget("this expansion's")
    key = _key(request)
    if key is not None and (kept := _EXPANSIONS.get(key)) is not None and kept.unchanged():
        _EXPANSIONS.move_to_end(key)
        if key not in budget.shown:  # xacro's warnings, once per config as if it had expanded the file
            budget.shown.add(key)
            _show_warnings(kept.warnings)
        return kept.text
    left = budget.left(limits)
    if left < SMALLEST_SLICE_S:
        raise UserError(budget.exhausted(request), where)
    slice_limits = Limits(limits.memory_mb, min(limits.timeout_s, left))
    started = time.monotonic()
    try:
        answer, warnings = _expand(request, slice_limits, budget, where)
    finally:
        budget.charge(time.monotonic() - started, request.shown)
    if key is not None:
        budget.shown.add(key)
        _remember(key, answer, warnings)
    return str(answer["text"])


def _expand(request: XacroRequest, limits: Limits, budget: XacroBudget, where: Where | None) -> tuple[dict[str, Any], bytes]:
    """The child's answer with a text, and what xacro printed; a UserError for any failure."""
    try:
        command = sandboxed_python("urdf_pipeline.urdf.xacro_sandbox", "xacro", "yaml")
    except ImportError as exc:
        raise UserError(f"expanding {request.shown} needs the {exc.args[0]} package: pip install xacro", where) from None
    payload = {
        "file": str(request.file),
        "shown": request.shown,
        "args": dict(request.args),
        "packages": {name: str(path) for name, path in request.package_paths.items()},
        "config_dir": str(request.confinement.config_dir),
        "read_roots": [str(root) for root in request.confinement.read_roots],
        "limits": {"memory_bytes": limits.memory_mb << 20, "cpu_seconds": int(limits.timeout_s) + 1, "output_bytes": ANSWER_BYTES},
    }
    try:
        outcome = _run(command, payload, limits)
    except OSError as exc:  # no process, no temporary file: still about expanding this file
        raise UserError(f"cannot expand {request.shown}: {exc}", where) from None
    answer = outcome.answer
    if answer is None or not ("text" in answer or "error" in answer):
        raise UserError(_failure(request, limits, budget, outcome), where)
    _show_warnings(outcome.head)
    if "error" in answer:
        raise UserError(str(answer["error"]), where)
    return answer, outcome.head


def _run(command: list[str], payload: dict[str, Any], limits: Limits) -> ChildOutcome:
    """The child's outcome (a name of its own: the tests count the expansions that start a child)."""
    environment = passed_environment(_PASSED_ENV)
    return run_bounded_child(
        command, payload, timeout_s=limits.timeout_s, env=environment, answer_bytes=ANSWER_BYTES, stderr_bytes=SHOWN_STDERR
    )


def _failure(request: XacroRequest, limits: Limits, budget: XacroBudget, outcome: ChildOutcome) -> str:
    """Why the child gave no answer (`run_bounded_child`'s kind), in xacro's words: stopped at the time bound, its own
    slowness or a budget the expansions before it used."""
    expansion, raise_it = f"xacro expansion of {request.shown}", "the person running the tool can raise the bound with"
    shared = budget.spent > 0 and budget.spenders
    if shared and outcome.kind in ("time", "cpu"):
        return (
            f"{expansion} did not end within the {limits.timeout_s:.3g} s left of {budget.owner} xacro time "
            f"budget of {budget.seconds:g} s and was stopped (the expansions before it took the rest: {listing(budget.spenders)}); "
            f"the person running the tool can raise the budget with {TIMEOUT_ENV}"
        )
    if outcome.kind == "time":
        return f"{expansion} did not end within {limits.timeout_s:g} s and was stopped (a macro or expression that never ends?); {raise_it} {TIMEOUT_ENV}"
    return {
        "cpu": f"{expansion} used more than {limits.timeout_s:g} s of CPU time and was stopped (a macro or expression that never ends?); {raise_it} {TIMEOUT_ENV}",
        "memory": f"{expansion} needs more than {limits.memory_mb} MB of memory (a property or macro that grows without end?); {raise_it} {MEMORY_ENV}",
        "oversized": f"{expansion} is larger than {OUTPUT_BYTES >> 20} MB of URDF text",
    }.get(outcome.kind, f"{expansion} failed ({outcome.status})" + (f": {shown(outcome.last)}" if outcome.last else ""))


def _show_warnings(data: bytes) -> None:
    """xacro's own warnings (deprecations, unknown attributes), as it would have printed them, shortened, and each line
    neutral: they quote the xacro file's own text (an include's filename), which may hold a newline and a workflow
    command."""
    if data:
        text = data[:SHOWN_STDERR].decode("utf-8", "replace")
        sys.stderr.write(neutral_text(text if text.endswith("\n") else text + "\n"))
        if len(data) > SHOWN_STDERR:
            sys.stderr.write(f"(xacro printed more; the first {SHOWN_STDERR >> 10} KB are shown)\n")

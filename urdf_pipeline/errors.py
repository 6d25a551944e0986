"""The one error family users see: each carries where the config is at fault. Warnings go through `warn`."""

from __future__ import annotations

import difflib
import logging
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path


class ExitCode(IntEnum):
    """Every exit status of the command line, in one place (README, "Exit status and faults")."""

    OK = 0
    USER_ERROR = 1  # one `error: FILE:LINE:COL: ...` line per problem, no traceback
    USAGE = 2  # bad command-line usage (argparse's own code)
    DOES_NOT_FIT = 3  # `check` only: sampled values do not fit the limits with the config's corrections
    BUG = 70  # an internal bug, with a traceback (EX_SOFTWARE)
    # `diff --exit-code`, as diff(1): 0 equal, 1 the plans differ, 2 any error (a user error, a bug; Ctrl-C stays 130)
    DIFFERENT = 1
    DIFF_TROUBLE = 2
    INTERRUPTED = 130  # Ctrl-C: 128 + SIGINT
    BROKEN_PIPE = 141  # stdout closed early (`| head`): 128 + SIGPIPE
    TERMINATED = 143  # SIGTERM, handled as Ctrl-C: 128 + SIGTERM


@dataclass(frozen=True)
class Where:
    """A place in a config (or sidecar) file: the file, the 1-based line, the YAML path and the 1-based column.

    Line 0 means the file as a whole; column 0 means the column is unknown. A Where made by `Document.where` points
    where its YAML path's entry starts: at the key for a mapping entry (`j1` in `j1: panda_joint1`, for a problem with
    the key or with its value alike), at the item for a sequence item."""

    file: Path
    line: int
    path: str = ""
    column: int = 0

    def prefix(self) -> str:
        """`FILE:LINE:COL`, `FILE:LINE` when the column is unknown, just `FILE` for the file as a whole (line 0)."""
        if not self.line:
            return str(self.file)
        return f"{self.file}:{self.line}:{self.column}" if self.column else f"{self.file}:{self.line}"


def listing(items: Sequence[str], limit: int = 12, separator: str = ", ", empty: str = "") -> str:
    """`a, b, c and 4 more`: names in a message, shortened so one error stays one readable line."""
    if not items:
        return empty
    return separator.join(items[:limit]) + (f" and {len(items) - limit} more" if len(items) > limit else "")


def located(severity: str, message: str, where: Where | None) -> str:
    """The one-line form of a problem: `SEVERITY: FILE:LINE:COL: YAML.PATH: message`."""
    place = f"{where.prefix()}: " if where else ""
    path = f"{where.path}: " if where and where.path else ""
    return f"{severity}: {place}{path}{message}"


class UserError(Exception):
    """A problem the user can fix in their config or data. Printed as `error: FILE:LINE:COL: message`, exit 1."""

    def __init__(self, message: str, where: Where | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.where = where

    def lines(self) -> list[str]:
        return [located("error", self.message, self.where)]


class UserErrors(UserError):
    """Several independent problems found in one pass (schema validation, joint coverage, ...)."""

    def __init__(self, errors: list[UserError]) -> None:
        super().__init__("; ".join(e.message for e in errors), errors[0].where if errors else None)
        self.errors = errors

    def lines(self) -> list[str]:
        return [line for error in self.errors for line in error.lines()]


class Problems:
    """Collects independent user errors so one run reports all of them, not just the first."""

    def __init__(self) -> None:
        self.errors: list[UserError] = []

    def add(self, message: str, where: Where | None) -> None:
        self.errors.append(UserError(message, where))

    def extend(self, error: UserError) -> None:
        self.errors.extend(error.errors if isinstance(error, UserErrors) else [error])

    def raise_if_any(self) -> None:
        if len(self.errors) == 1:
            raise self.errors[0]
        if self.errors:
            raise UserErrors(self.errors)


@dataclass(frozen=True)
class ConfigWarning:
    """Something the config does on purpose that a reviewer should see (an assumed pose, invisible meshes)."""

    message: str
    where: Where | None = None

    def line(self) -> str:
        return located("warning", self.message, self.where)


WarningHandler = Callable[[ConfigWarning], None]


def show_warning(warning: ConfigWarning) -> None:
    """To the `urdf_pipeline` logger (see progress.py), which the command line prints on stderr."""
    logging.getLogger("urdf_pipeline").warning(warning.line())


_warning_handler: ContextVar[WarningHandler] = ContextVar("warning_handler", default=show_warning)


def warn(message: str, where: Where | None = None) -> None:
    """Report a warning: printed as `warning: FILE:LINE:COL: YAML.PATH: message` on stderr, unless collected."""
    _warning_handler.get()(ConfigWarning(message, where))


@contextmanager
def collect_warnings() -> Iterator[list[ConfigWarning]]:
    """Within the block, `warn` appends to the yielded list instead of printing (for `validate --format github|json`)."""
    collected: list[ConfigWarning] = []
    token = _warning_handler.set(collected.append)
    try:
        yield collected
    finally:
        _warning_handler.reset(token)


# 'Did you mean': one rule for every misspelled name, so a suggestion appears only for a close match.
CUTOFF = 0.75  # difflib ratio: a typo or two in a joint/frame name passes, another name of the robot does not


def closest(name: str, choices: Iterable[str]) -> str | None:
    """The choice closest to `name` (case-insensitive), if it is close enough to be the name meant."""
    by_folded = {choice.casefold(): choice for choice in sorted(choices, reverse=True)}
    close = difflib.get_close_matches(name.casefold(), list(by_folded), n=1, cutoff=CUTOFF)
    return by_folded[close[0]] if close else None


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """` (did you mean 'x'?)` to append to a message, or nothing."""
    close = closest(name, choices)
    return f" (did you mean '{close}'?)" if close is not None else ""

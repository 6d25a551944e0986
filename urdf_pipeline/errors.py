"""The one error family users see: each carries where the config is at fault. Warnings go through `warn`."""

from __future__ import annotations

import difflib
import logging
import re
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path


class ExitCode(IntEnum):
    """Every exit status of the command line, in one place (docs/security.md, "Exit status and faults")."""

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

    @staticmethod
    def for_signal(signum: int) -> int:
        """The status of a command a signal stopped, whichever command: the shell's 128 + its number, so that a script
        tells "it ended" (0) from "I stopped it" (130 Ctrl-C, 143 SIGTERM)."""
        return 128 + int(signum)


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


# Text from input (a pull request's file names, YAML keys and values, URDF names, a child's stderr) shown to a person
# or to CI: one line, every control character visible, bounded, never a GitHub workflow command. `shown`/`quoted` for a
# name inside a message; `neutral_line`/`neutral_text` at the places where lines leave the tool (`located`, the
# logger's formatter, the renderers).
NAME_LIMIT = 200  # characters of one name in a message; a longer one is shortened, with its length
LINE_LIMIT = 2000  # characters of one output line; a longer one is shortened, with its length
# C0, DEL, C1, bidi embeddings/overrides/isolates and marks, line/paragraph separators, BOM: what no name from input may
# show raw, and what a file name that becomes a segment id may not hold (`has_control_character`)
_CONTROL_CHARACTERS = "\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069\ufeff"
_CONTROL_IN_NAME = re.compile(f"[{_CONTROL_CHARACTERS}]")
# escaped for output: those, and lone surrogates (an undecodable file name: printing one raw would fail on a strict stdout)
_CONTROL = re.compile(f"[{_CONTROL_CHARACTERS}\ud800-\udfff]")
_NAMED_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}
# Lines a GitHub Actions runner reads as a workflow command (`::error ...`, the older `##[error]...`), after it trims
# leading whitespace. A line of ours that would start so gets COMMAND_GUARD in front.
_COMMAND_START = ("::", "##[")
COMMAND_GUARD = "\\"


def _escape(match: re.Match[str]) -> str:
    char = match.group()
    return _NAMED_ESCAPES.get(char) or (f"\\x{ord(char):02x}" if ord(char) < 0x100 else f"\\u{ord(char):04x}")


def escaped(text: str) -> str:
    """Control characters made visible (`\\n`, `\\x1b`, `\\u202e`): text from input never moves the cursor, colours a
    terminal, reorders what a reviewer reads or splits one line in two. Backslashes stay as they are."""
    return _CONTROL.sub(_escape, text)


def has_control_character(text: str) -> bool:
    """Whether `text` holds a character `escaped` would show escaped (lone surrogates aside: undecodable bytes of a
    file name are not control characters)."""
    return _CONTROL_IN_NAME.search(text) is not None


def _keep(limit: int) -> int:
    """Characters kept at each end of a shortened text: with `…` and ` (1,234,567 characters)`, within `limit`."""
    return max((limit - 30) // 2, 1)


def shortened(text: str, limit: int) -> str:
    """`head…tail (5,000 characters)` for a text longer than `limit`; as it is otherwise."""
    if len(text) <= limit:
        return text
    keep = _keep(limit)
    return f"{text[:keep]}…{text[-keep:]} ({len(text):,} characters)"


def shown(text: object, limit: int = NAME_LIMIT) -> str:
    """A name (or any value from input) as a message shows it: one line, control characters visible, and shortened
    with its length when longer than `limit` characters (`aaaa…aaaa (5,000 characters)`)."""
    return escaped(shortened(str(text), limit))


def quoted(text: object, limit: int = NAME_LIMIT) -> str:
    """`'name'`, as messages quote names; a long one as `'aaaa…aaaa' (5,000 characters)`."""
    text = str(text)
    if len(text) <= limit:
        return f"'{escaped(text)}'"
    keep = _keep(limit)
    return f"'{escaped(text[:keep])}…{escaped(text[-keep:])}' ({len(text):,} characters)"


def neutral_line(line: str, limit: int = LINE_LIMIT) -> str:
    """One line as the tool prints it: control characters visible (a newline inside becomes `\\n`), shortened past
    `limit` (as escaped), and never read by GitHub Actions as a workflow command (`::error::...`, `::add-mask::...`):
    such a line gets a backslash in front."""
    line = shortened(escaped(line), limit)
    return COMMAND_GUARD + line if line.lstrip().startswith(_COMMAND_START) else line


def neutral_text(text: str, limit: int = LINE_LIMIT) -> str:
    """Every line of a text the tool prints (split at newlines only: a CR or any other control character inside a
    line is made visible), each through `neutral_line`. A final newline stays."""
    body, end = (text[:-1], "\n") if text.endswith("\n") else (text, "")
    return "\n".join(neutral_line(line, limit) for line in body.split("\n")) + end if text else text


def listing(items: Sequence[str], limit: int = 12, separator: str = ", ", empty: str = "") -> str:
    """`a, b, c and 4 more`: names in a message, shortened so one error stays one readable line (each name too)."""
    if not items:
        return empty
    return separator.join(shown(item) for item in items[:limit]) + (f" and {len(items) - limit:,} more" if len(items) > limit else "")


def located(severity: str, message: str, where: Where | None) -> str:
    """The one-line form of a problem: `SEVERITY: FILE:LINE:COL: YAML.PATH: message`, neutral (one line, bounded,
    control characters visible, never a workflow command) whatever the file name, YAML keys and message hold."""
    place = f"{shown(where.prefix(), LINE_LIMIT // 4)}: " if where else ""
    path = f"{shown(where.path, LINE_LIMIT // 4)}: " if where and where.path else ""
    return neutral_line(f"{severity}: {place}{path}{message}")


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
    """To the `urdf_pipeline` logger (see logs.py), which the command line prints on stderr."""
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
    return f" (did you mean {quoted(close)}?)" if close is not None else ""


HINTED = 20  # misspelled names of one check that get a "did you mean"


class Hints:
    """ "Did you mean" for the first HINTED misspelled names of one check, then nothing: each hint compares a name with
    every choice, so a file or config of 20,000 wrong names must not ask for all of them (that is quadratic)."""

    def __init__(self, limit: int = HINTED) -> None:
        self.left = limit

    def allowed(self) -> bool:
        """Whether this problem still gets a hint (counts it): for a check with a rule of its own (a looser cutoff)."""
        self.left -= 1
        return self.left >= 0

    def __call__(self, name: str, choices: Iterable[str]) -> str:
        """`did_you_mean(name, choices)` while hints are allowed, else nothing."""
        return did_you_mean(name, choices) if self.allowed() else ""

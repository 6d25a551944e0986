"""The one error family users see: each carries where the config is at fault."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Where:
    """A place in a config (or sidecar) file: the file, the 1-based line and the YAML path."""

    file: Path
    line: int
    path: str = ""

    def prefix(self) -> str:
        """`FILE:LINE`, or just `FILE` when the problem is the file as a whole (line 0)."""
        return f"{self.file}:{self.line}" if self.line else str(self.file)


def listing(items: Sequence[str], limit: int = 12, separator: str = ", ", empty: str = "") -> str:
    """`a, b, c and 4 more`: names in a message, shortened so one error stays one readable line."""
    if not items:
        return empty
    return separator.join(items[:limit]) + (f" and {len(items) - limit} more" if len(items) > limit else "")


class UserError(Exception):
    """A problem the user can fix in their config or data. Printed as `error: FILE:LINE: message`, exit 1."""

    def __init__(self, message: str, where: Where | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.where = where

    def lines(self) -> list[str]:
        located = f"{self.where.prefix()}: " if self.where else ""
        path = f"{self.where.path}: " if self.where and self.where.path else ""
        return [f"error: {located}{path}{self.message}"]


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

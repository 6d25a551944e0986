"""`plan --render DIR` and `diff --render DIR`: the pictures drawn by the Rerun viewer, as the reports list them
(paths as the command line gave the folder, so the text names the files beside it)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..plan import Plan
from .diff.diff_base import Change
from .plan_report.report_model import PictureEntry

if TYPE_CHECKING:
    from ..render import Picture, Size


def plan_pictures(plan: Plan, folder: Path, size: Size | None) -> tuple[PictureEntry, ...]:
    from ..render import DEFAULT_SIZE, render_plan

    return _announced(lambda: render_plan(plan, folder, size or DEFAULT_SIZE))


def diff_pictures(
    old: Plan, new: Plan, folder: Path, stem: str, size: Size | None, names: tuple[str, str], changes: Sequence[Change] = ()
) -> tuple[PictureEntry, ...]:
    """Old, new, side by side, and the old as a ghost over the new whose caption lists `changes` (named as the report
    names the configs: `OLD`, `CONFIG@REV`)."""
    from ..render import DEFAULT_SIZE, DiffNames, render_diff

    return _announced(lambda: render_diff(old, new, folder, stem, size or DEFAULT_SIZE, DiffNames(*names, caption_changes(changes))))


def _announced(draw: Callable[[], tuple[Picture, ...]]) -> tuple[PictureEntry, ...]:
    """The pictures `draw` draws, announced with the time they took, as the reports list them."""
    from ..render import announce

    started = time.perf_counter()
    pictures = draw()
    announce(pictures, time.perf_counter() - started)
    return tuple(PictureEntry(picture.label, str(picture.path)) for picture in pictures)


def caption_changes(changes: Sequence[Change]) -> tuple[str, ...]:
    """The changes as the overlay's caption lists them: what moves the robot first (a moved edge or joint origin, a
    remapped joint), each a short line (a move without its before/after values); the rest in report order."""
    return tuple(_short(change) for change in sorted(changes, key=_rank))


def _rank(change: Change) -> int:
    if _moved(change):
        return 0
    return 1 if ": remapped " in change.detail else 2


def _moved(change: Change) -> bool:
    return change.detail.startswith("moved ") or ": origin moved " in change.detail


def _short(change: Change) -> str:
    detail = change.detail.split(" (", 1)[0] if _moved(change) else change.detail
    return f"{change.subject}: {detail}"

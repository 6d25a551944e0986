"""`plan --render DIR` and `diff --render DIR`: the pictures drawn by the Rerun viewer, as the reports list them
(paths as the command line gave the folder, so the text names the files beside it)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

from ..plan import Plan
from .plan_report.report_model import PictureEntry

if TYPE_CHECKING:
    from ..render import Picture, Size


def _entries(pictures: tuple[Picture, ...]) -> tuple[PictureEntry, ...]:
    return tuple(PictureEntry(picture.label, str(picture.path)) for picture in pictures)


def plan_pictures(plan: Plan, folder: Path, size: Size | None) -> tuple[PictureEntry, ...]:
    from ..render import DEFAULT_SIZE, announce, render_plan

    started = time.perf_counter()
    pictures = render_plan(plan, folder, size or DEFAULT_SIZE)
    announce(pictures, time.perf_counter() - started)
    return _entries(pictures)


def diff_pictures(old: Plan, new: Plan, folder: Path, stem: str, size: Size | None) -> tuple[PictureEntry, ...]:
    from ..render import DEFAULT_SIZE, announce, render_diff

    started = time.perf_counter()
    pictures = render_diff(old, new, folder, stem, size or DEFAULT_SIZE)
    announce(pictures, time.perf_counter() - started)
    return _entries(pictures)

"""Write a recording atomically: beside the target, then renamed; a failed run leaves nothing behind."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import UserError
from .plan import OutputPlan

if TYPE_CHECKING:
    from rerun.chunk import ChunkStore


def write_atomically(store: ChunkStore, output: OutputPlan) -> Path:
    target = output.path
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output directory {target.parent}: {exc}", output.where) from None
    partial = target.with_name(f".{target.name}.partial-{os.getpid()}")
    try:
        store.write_rrd(partial, application_id=output.application_id, recording_id=output.recording_id)
        os.replace(partial, target)
    except OSError as exc:  # disk full, a directory in the way, permissions: the machine, not a bug
        partial.unlink(missing_ok=True)
        raise UserError(f"cannot write {target}: {exc}", output.where) from None
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return target


def write_file_atomically(target: Path, write: Callable[[Path], None]) -> Path:
    """`write(partial)` beside the target, then renamed into place (for files other than recordings: the blueprint)."""
    partial = target.with_name(f".{target.name}.partial-{os.getpid()}")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        write(partial)
        os.replace(partial, target)
    except (OSError, RuntimeError) as exc:
        partial.unlink(missing_ok=True)
        raise UserError(f"cannot write {target}: {exc}") from None
    return target

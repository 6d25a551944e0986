"""`run --base`: a layer attaches to a base recording only through equal recording ids; check them before running.

A layer whose segment id is not among the base recordings would be written, registered, and never seen next to its
episode. Reads only each base file's manifest (its store ids), not its data.
"""

from __future__ import annotations

import glob
import itertools
from dataclasses import dataclass
from pathlib import Path

from ..confine import file_state, resolved_or_written
from ..errors import UserError, Where, listing, shown
from ..plan import Plan

WHERE = Where(Path("--base"), 0)


@dataclass(frozen=True)
class BaseRecording:
    """A base file holding a recording: the file and the recording's application id."""

    path: Path
    application_id: str


def base_files(base: str) -> dict[str, tuple[BaseRecording, ...]]:
    """recording_id -> the base files that hold it (a recording may span files), in path order: every .rrd in a
    directory (recursively) or matching a glob. `run --base` checks the ids, `browse --base` opens the files. Each file
    must stay, symbolic links followed, inside the folder `--base` names (a glob's folder: the part before its first
    wildcard), be a regular file (a FIFO would never end) and hold a Rerun recording; `path` is the file resolved."""
    from rerun.chunk import RrdReader

    root = Path(base)
    folder = root if root.is_dir() else _glob_folder(base)
    paths = sorted(root.glob("**/*.rrd")) if root.is_dir() else sorted(Path(p) for p in glob.glob(base, recursive=True))
    if not paths:
        raise UserError(f"no .rrd file in {shown(base)} (give a directory of base recordings or a glob such as 'base/*.rrd')", WHERE)
    inside = resolved_or_written(folder)
    found: dict[str, list[BaseRecording]] = {}
    for path in paths:
        real = resolved_or_written(path)
        if not real.is_relative_to(inside):
            raise UserError(
                f"base recording {shown(str(path))} resolves to {shown(str(real))}, outside {shown(str(folder))}: a symbolic link "
                "out of the folder --base names is not followed; copy the recording into it",
                WHERE,
            )
        if file_state(real, "base recording", WHERE) == "folder":
            continue  # a folder named x.rrd: nothing to read
        try:
            entries = RrdReader(real).recordings()
        except (OSError, ValueError, RuntimeError) as exc:
            raise UserError(f"cannot read base recording {shown(str(path))}: {shown(exc)}", WHERE) from None
        for entry in entries:
            found.setdefault(str(entry.recording_id), []).append(BaseRecording(real, str(entry.application_id)))
    return {recording: tuple(files) for recording, files in found.items()}


def _glob_folder(pattern: str) -> Path:
    """The folder a glob reads under: its leading parts without a wildcard (`base/*/x.rrd` -> `base`)."""
    parts = Path(pattern).parts
    fixed = list(itertools.takewhile(lambda part: not glob.has_magic(part), parts))
    return Path(*fixed) if fixed and len(fixed) < len(parts) else Path(pattern).parent if fixed else Path(".")


def check_base(plan: Plan, base: str) -> int:
    """Every segment id must be a base recording's, with the same application id; returns how many were matched."""
    found = {recording: files[-1].application_id for recording, files in base_files(base).items()}  # the last file's, in path order
    segments = [s.id for s in plan.segments]
    missing = [s for s in segments if s not in found]
    if missing:
        close = sorted(found)[:3]
        raise UserError(
            f"{len(missing)} of {len(segments)} segment(s) have no base recording in {base}: {listing(missing)}; a layer attaches "
            f"only to a recording with the same recording_id (the base has e.g. {listing(close, empty='none')}): fix output.segment",
            plan.dataset.where if plan.dataset else WHERE,
        )
    other_apps = sorted({found[s] for s in segments if found[s] != plan.application_id})
    if other_apps:
        raise UserError(
            f"the base recordings have application_id {listing(other_apps)}, this config '{plan.application_id}': "
            "a viewer shows them apart; set output.application_id to the base's",
            plan.output_where,
        )
    return len(segments)

"""`browse --base DIR_OR_GLOB`: the base recordings a segment opens with, found by recording id.

The same form and reading rules as `run --base` (`dataset.base_check`): every `.rrd` under a directory (recursively)
or matching a glob, each file's store ids read from its manifest (not its data); no `.rrd` there, or one that cannot
be read, is a `UserError` at `--base`. Like `run --base` (and `-o DIR`) it is a command-line argument of whoever runs
the tool, not a path a config names: it is not confined to the config's roots. A segment attaches to the files
holding a recording with its id; the web viewer merges recordings of the same recording id into one.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

from ..errors import UserError, Where

WHERE = Where(Path("--base"), 0)


@dataclass(frozen=True)
class BaseRecording:
    """A base file holding a recording: the file and the recording's application id."""

    path: Path
    application_id: str


def base_files(base: str) -> dict[str, tuple[BaseRecording, ...]]:
    """recording_id -> the base files that hold it (a recording may span files), in path order."""
    from rerun.chunk import RrdReader

    root = Path(base)
    paths = sorted(root.glob("**/*.rrd")) if root.is_dir() else sorted(Path(p) for p in glob.glob(base, recursive=True))
    if not paths:
        raise UserError(f"no .rrd file in {base} (give a directory of base recordings or a glob such as 'base/*.rrd')", WHERE)
    found: dict[str, list[BaseRecording]] = {}
    for path in paths:
        try:
            entries = RrdReader(path).recordings()
        except (OSError, ValueError, RuntimeError) as exc:
            raise UserError(f"cannot read base recording {path}: {exc}", WHERE) from None
        for entry in entries:
            found.setdefault(str(entry.recording_id), []).append(BaseRecording(path, str(entry.application_id)))
    return {recording: tuple(files) for recording, files in found.items()}

"""Write a recording atomically: beside the target, then renamed; a failed run leaves nothing behind.

The tool never replaces a file it did not write (a config from a pull request must not be able to clobber the
repository's files), whatever `--force` says: an existing recording must carry the pipeline's recording property, a
manifest the pipeline's key, a blueprint only a blueprint. Partial files are named `.NAME.partial-PID` beside their
target, so a run can tell its own leftovers (a process killed with SIGKILL) from anything else.
"""

from __future__ import annotations

import os
import re
import stat
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Literal

from ..confine import file_state, os_cause
from ..errors import UserError, Where

Kind = Literal["recording", "manifest", "blueprint"]
OUR_PROPERTIES = ("/__properties/urdf_pipeline ", "/__properties/urdf_pipeline_model ")  # provenance.py's, as summary() lists them
MANIFEST_KEY = "urdf_pipeline"  # manifest.py writes the pipeline's version under it
PARTIAL = re.compile(r"^\.(?P<name>.+)\.partial-(?P<pid>\d+)$")
WRITTEN_SUFFIXES = (".rrd", ".json", ".rbl")  # what a run writes: recordings, the manifest, the blueprint


def write_file_atomically(
    target: Path, write: Callable[[Path], object], kind: Kind | None = "blueprint", where: Where | None = None
) -> Path:
    """`write(partial)` beside the target, then renamed into place. The target must be a file of ours of `kind`
    (checked again here: it may have appeared since the run started; None: the caller checked it, as the manifest,
    rewritten every second, is checked once when loaded); a failure leaves no partial file and is a user error."""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output directory {target.parent}: {exc}", where) from None
    if kind is not None:
        require_ours(target, kind, where)
    partial = target.with_name(f".{target.name}.partial-{os.getpid()}")
    try:
        write(partial)
        os.replace(partial, target)
    except (OSError, RuntimeError) as exc:  # disk full, a directory in the way, permissions: the machine, not a bug
        partial.unlink(missing_ok=True)
        raise UserError(f"cannot write {target}: {exc}", where) from None
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return target


def foreign_reason(path: Path, kind: Kind) -> str | None:
    """Why the existing `path` is not a file this tool wrote; None when it is ours (or does not exist)."""
    try:
        status = os.lstat(path)
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:  # a name too long, a file in place of a folder, no permission
        return f"it cannot be examined ({os_cause(exc, path)})"
    if stat.S_ISLNK(status.st_mode):
        return "it is a symbolic link"
    if not stat.S_ISREG(status.st_mode):
        return "it is not a regular file"
    if kind == "manifest":
        import json

        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            return "it is not JSON"
        return None if isinstance(data, dict) and MANIFEST_KEY in data and "format" in data else f"it has no '{MANIFEST_KEY}' key"
    from rerun.chunk import RrdReader

    try:  # the file's footer (manifest) only: no chunk is read
        reader = RrdReader(path)
        recordings, blueprints = reader.recordings(), reader.blueprints()
        if kind == "blueprint":
            return None if blueprints and not recordings else "it is not a Rerun blueprint"
        if len(recordings) != 1:
            return "it is not a Rerun recording"
        lines = reader.store().summary().splitlines()
    except (OSError, ValueError, RuntimeError):
        return "it is not a Rerun recording"
    return None if any(line.startswith(OUR_PROPERTIES) for line in lines) else "it is a recording that urdf-pipeline did not write"


def require_ours(path: Path, kind: Kind, where: Where | None) -> None:
    reason = foreign_reason(path, kind)
    if reason is not None:
        raise UserError(
            f"cannot write {path}: it exists and {reason}; urdf-pipeline never overwrites a file it did not write (not even "
            "with --force): delete or move it, or choose another output path",
            where,
        )


def require_writable(directory: Path, where: Where | None) -> None:
    """`directory` exists and takes new files, or can be made: checked before computing anything."""
    existing = directory
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    if file_state(existing, f"cannot write to {directory}:", where, "used") != "folder":
        raise UserError(f"cannot write to {directory}: {existing} is not a directory; choose another output path", where)
    if existing != directory:
        if not os.access(existing, os.W_OK | os.X_OK):
            raise UserError(f"cannot create {directory}: {existing} is not writable; choose another output path", where)
        return
    try:  # access() is not the whole truth (read-only mounts, ACLs): make a file
        handle, probe = tempfile.mkstemp(prefix=".urdf-pipeline-probe-", dir=directory)
    except OSError as exc:
        raise UserError(f"cannot write to {directory}: {exc.strerror or exc}; choose another output path", where) from None
    os.close(handle)
    os.unlink(probe)


def remove_stale_partials(directories: Iterable[Path]) -> list[Path]:
    """Remove, in `directories`, the pipeline's partial files (`.NAME.partial-PID` of a recording, manifest or
    blueprint) whose process is gone: what a run killed with SIGKILL, or a crashed machine, left behind."""
    removed = []
    for directory in dict.fromkeys(directories):
        try:
            entries = os.listdir(directory)
        except OSError:
            continue  # not there yet: nothing to clean
        for entry in entries:
            match = PARTIAL.match(entry)
            if match and match["name"].endswith(WRITTEN_SUFFIXES) and not process_alive(int(match["pid"])):
                (directory / entry).unlink(missing_ok=True)
                removed.append(directory / entry)
    return removed


def process_alive(pid: int) -> bool:
    """Whether process `pid` exists (another user's process counts: it cannot be signalled, but it is there)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextmanager
def folders_removed_if_left_empty(folders: Iterable[Path]) -> Iterator[None]:
    """The folders missing now on the way to each of `folders` (what the block may make) are removed when the block
    ends if they hold nothing but empty folders: a refused or stopped command leaves no empty output folder behind,
    and a folder that was there is left as it was. Call it where no other process of the run writes any more."""
    made: dict[Path, None] = {}
    for folder in dict.fromkeys(folders):
        top = None
        while not os.path.lexists(folder) and folder != folder.parent:
            top, folder = folder, folder.parent
        if top is not None:
            made[top] = None
    try:
        yield
    finally:
        for top in made:
            for inner, _, _ in sorted(os.walk(top), key=lambda entry: -len(entry[0])):  # the deepest first
                try:
                    os.rmdir(inner)
                except OSError:  # not empty: something was written there
                    pass

"""What every source kind shares: the protocol a kind module follows, how a config's input path is resolved, and the
typed description a kind gives `init` (plain data: `scaffold/` turns it into YAML, `sources/` never imports `scaffold/`)."""

from __future__ import annotations

import glob
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from ..config import Document
from ..confine import Unresolvable, confinement_for, file_state, refuse_url, resolved
from ..errors import UserError, Where, escaped, has_control_character
from .stream import SourceStream

GLOB = re.compile(r"[*?\[]")


def refuse_control_characters(path: str | Path, what: str, where: Where | None, fix: str = "rename the file") -> None:
    """A name holding a control character (errors.has_control_character: a newline, an escape, a direction override)
    is refused, shown escaped: it becomes a segment id, a recording id, an output file name and a line of review
    output (a newline would start a forged `::error::` line)."""
    text = str(path)
    if has_control_character(text):
        raise UserError(
            f"{what} '{escaped(text)}' holds a control character (a newline, a tab, an escape, a direction override); "
            f"it would become a segment id, a recording id and an output file name: {fix}",
            where,
        )


@dataclass(frozen=True)
class EntryField:
    """One key of the config entry `init` proposes for a source; `comment` says why when the value is a guess."""

    key: str
    value: Any  # a scalar, or a flow mapping such as {timestamp: COL, unit: s}
    comment: str = ""


@dataclass(frozen=True)
class SourceDescription:
    """A source as its metadata describes it (never its values): what `init` writes for it and how it matches names."""

    kind: str  # the config key that selects the kind
    fields: tuple[EntryField, ...]  # the entry's keys after the kind's own path (`column`, `topic`, ...), in order
    names: tuple[str, ...] | None  # None: the metadata has no names; the values are matched by position
    width: int | None  # values per row when known (sources without names)
    segment: str  # the output.segment template
    pattern: bool = False  # the path is a glob: a globbed source, one segment per file
    unnamed: str = ""  # why there are no names ("parquet carries no names")
    urdf_order: bool = False  # the names come in any order, row by row: the map follows the URDF's joint order
    notes: tuple[str, ...] = ()  # comment lines for the entry


class SourceKind(Protocol):
    """A source kind module: `PLAN_TYPE` (its plan dataclass), `compile_source` (config -> plan, reading metadata
    only, so `validate` can run it), `open_stream` (plan -> a lazy stream of joint values), and for `init`:
    `SPEC_FORM` (`parquet:FILE[#COLUMN]`), `SUFFIXES` (file suffixes that say the kind) and `describe` (a path and
    the PART of `KIND:PATH#PART` -> a `SourceDescription`, from metadata only)."""

    @property
    def PLAN_TYPE(self) -> type: ...  # a module constant, read-only here so each kind may narrow it

    @property
    def SPEC_FORM(self) -> str: ...

    @property
    def SUFFIXES(self) -> tuple[str, ...]: ...

    def compile_source(self, name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> Any: ...

    def open_stream(self, plan: Any) -> SourceStream: ...

    def describe(self, name: str, path: str, part: str | None, document: Document) -> SourceDescription: ...

    def check_download(self, plan: Any) -> None: ...  # a remote file's data checks, once `run` downloaded it


def rooted(path: str) -> str:
    """An entity or a dataset path as Rerun's readers name it: one leading `/`, none trailing."""
    return "/" + path.strip("/")


def shown_file(plan: Any) -> str:
    """A file source as its messages name it: a remote file by its URL (not the download cache's path), else its path."""
    remote = getattr(plan, "remote", None)
    return str(remote.url) if remote is not None else str(plan.path)


def resolve_input(document: Document, config_dir: Path, path: str, *where: str | int, directory: bool = False) -> Path:
    """A path from the config, relative to the config file; it must exist. A path the OS cannot follow (a symlink
    loop, a name too long, a file in place of a folder, a FIFO) is a user error at the path's key."""
    located = document.where(*where)
    what = f"{where[-1]} {'folder' if directory else 'file'}"  # "parquet file", "lerobot folder"
    refuse_control_characters(path, what, located)
    refuse_url(path, what, located)  # a kind that reads remote files takes its URL before this
    named = config_dir / path  # an absolute `path` stays itself, and is shown as given (a glob's match, a link)
    try:
        real = named if Path(path).is_absolute() else resolved(named)
    except Unresolvable as exc:
        if config_dir != document.file.parent:
            raise UserError(f"{what} {named} cannot be read: {exc.cause}", located) from None
        real = named  # check_read says why (or refuses it by the rule, when it points outside)
    if config_dir == document.file.parent:  # a config's path; `init` passes the input's own folder: named at the terminal
        real = confinement_for(document.file).check_read(real, what, located)  # before existence: no probing
    state = file_state(real, what, located)
    if state != ("folder" if directory else "file"):
        kind = "directory" if directory else "file"
        shown = f"{real} is a {state}, not a {kind}" if state != "missing" else f"{kind} not found: {real}"
        raise UserError(f"{shown} (paths are relative to the config file)", located)
    return real


@dataclass(frozen=True)
class FileInput:
    """A file kind's PATH as `init` got it: the file whose metadata is read (a glob's first match), and the segment."""

    file: Path
    pattern: bool  # PATH is a glob
    segment: str  # `{stem}` for a glob, else the file's stem made safe for a recording id


def file_input(path: str) -> FileInput:
    """PATH (relative to the current folder, maybe a glob) of a file kind; it must name at least one file."""
    pattern = bool(GLOB.search(path))
    found = sorted(glob.glob(path, recursive=True)) if pattern else [path]
    files = []
    for match in found:
        refuse_control_characters(match, "file", None)
        try:
            real = resolved(match)
        except Unresolvable as exc:
            raise UserError(f"{match} cannot be read: {exc.cause}") from None
        state = file_state(real, "file", None)
        if state == "file":
            files.append(real)
        elif not pattern:
            raise UserError(f"{real} is a folder, not a file" if state == "folder" else f"file not found: {real}")
    if not files:
        raise UserError(f"'{path}' matches no file")
    if pattern:
        return FileInput(files[0], True, "{stem}")
    return FileInput(files[0], False, re.sub(r"[^A-Za-z0-9_.-]", "_", Path(path).name.split(".", 1)[0]) or "segment")

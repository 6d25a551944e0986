"""What every source kind shares: the protocol a kind module follows, how a config's input path is resolved, and the
typed description a kind gives `init` (plain data: `review/` turns it into YAML, `sources/` never imports `review/`)."""

from __future__ import annotations

import glob
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from ..config import Document
from ..confine import confinement_for
from ..errors import UserError
from .stream import SourceStream

GLOB = re.compile(r"[*?\[]")


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


def resolve_input(document: Document, config_dir: Path, path: str, *where: str | int, directory: bool = False) -> Path:
    """A path from the config, relative to the config file; it must exist."""
    resolved = (config_dir / path).resolve() if not Path(path).is_absolute() else Path(path)
    if config_dir == document.file.parent:  # a config's path; `init` passes the input's own folder: named at the terminal
        what = f"{where[-1]} {'folder' if directory else 'file'}"  # "parquet file", "lerobot folder"
        confinement_for(document.file).check_read(resolved, what, document.where(*where))  # before existence: no probing
    ok = resolved.is_dir() if directory else resolved.is_file()
    if not ok:
        kind = "directory" if directory else "file"
        raise UserError(f"{kind} not found: {resolved} (paths are relative to the config file)", document.where(*where))
    return resolved


@dataclass(frozen=True)
class FileInput:
    """A file kind's PATH as `init` got it: the file whose metadata is read (a glob's first match), and the segment."""

    file: Path
    pattern: bool  # PATH is a glob
    segment: str  # `{stem}` for a glob, else the file's stem made safe for a recording id


def file_input(path: str) -> FileInput:
    """PATH (relative to the current folder, maybe a glob) of a file kind; it must name at least one file."""
    pattern = bool(GLOB.search(path))
    if pattern:
        found = sorted(p for p in glob.glob(path, recursive=True) if Path(p).is_file())
        if not found:
            raise UserError(f"'{path}' matches no file")
        return FileInput(Path(found[0]).resolve(), True, "{stem}")
    resolved = Path(path).resolve()
    if not resolved.is_file():
        raise UserError(f"file not found: {resolved}")
    return FileInput(resolved, False, re.sub(r"[^A-Za-z0-9_.-]", "_", Path(path).name.split(".", 1)[0]) or "segment")

"""What every source kind shares: the protocol a kind module follows, and how a config's input path is resolved."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from ..config.document import Document
from ..confine import confinement_for
from ..errors import UserError
from .stream import SourceStream


class SourceKind(Protocol):
    """A source kind module: `PLAN_TYPE` (its plan dataclass), `compile_source` (config -> plan, reading metadata
    only, so `validate` can run it) and `open_stream` (plan -> a lazy stream of joint values)."""

    @property
    def PLAN_TYPE(self) -> type: ...  # a module constant, read-only here so each kind may narrow it

    def compile_source(self, name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> Any: ...

    def open_stream(self, plan: Any) -> SourceStream: ...


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

"""Joint-value sources. Each kind compiles its config (metadata only) and opens a lazy Rerun stream.

A kind is one module with `compile_source` (metadata only) and `open_stream` (a lazy SourceStream), registered in
KINDS under the config key that selects it.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import Any

from ..config.document import Document
from ..confine import confinement_for
from ..errors import UserError
from ..plan import SourcePlan
from . import hdf5, lerobot, mcap, parquet, rrd

KINDS: dict[str, ModuleType] = {"parquet": parquet, "lerobot": lerobot, "mcap": mcap, "hdf5": hdf5, "rrd": rrd}


def kind_of(spec: dict[str, Any]) -> str:
    return next(kind for kind in KINDS if kind in spec)


def compile_source(name: str, spec: dict[str, Any], document: Document) -> SourcePlan:
    kind = kind_of(spec)
    plan: SourcePlan = KINDS[kind].compile_source(name, spec, document, document.file.parent)
    return plan


def module_for(plan: SourcePlan) -> ModuleType:
    return next(module for module in KINDS.values() if isinstance(plan, module.PLAN_TYPE))


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

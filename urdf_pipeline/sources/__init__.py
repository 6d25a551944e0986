"""Joint-value sources. Each kind compiles its config (metadata only) and opens a lazy Rerun stream.

A kind is one module that follows `base.SourceKind` (`PLAN_TYPE`, `compile_source`, `open_stream`), registered in
KINDS under the config key that selects it. Kinds import `base` and their siblings, never this package's __init__.
"""

from __future__ import annotations

from typing import Any

from ..config.document import Document
from ..plan import SourcePlan
from . import hdf5, lerobot, mcap, parquet, rrd
from .base import SourceKind, resolve_input

__all__ = ["KINDS", "SourceKind", "compile_source", "kind_of", "module_for", "resolve_input"]

KINDS: dict[str, SourceKind] = {"parquet": parquet, "lerobot": lerobot, "mcap": mcap, "hdf5": hdf5, "rrd": rrd}


def kind_of(spec: dict[str, Any]) -> str:
    return next(kind for kind in KINDS if kind in spec)


def compile_source(name: str, spec: dict[str, Any], document: Document) -> SourcePlan:
    kind = kind_of(spec)
    plan: SourcePlan = KINDS[kind].compile_source(name, spec, document, document.file.parent)
    return plan


def module_for(plan: SourcePlan) -> SourceKind:
    return next(module for module in KINDS.values() if isinstance(plan, module.PLAN_TYPE))

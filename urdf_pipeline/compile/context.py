"""What every compile step shares, made once per config so no step threads the document and the problems on its own."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import Document
from ..confine import Confinement
from ..errors import Problems, Where
from ..urdf import XacroBudget

SourceNames = Mapping[str, tuple[str, ...] | None]
"""The names of each source's values, by source; None when only its data holds them (`validate --no-data`)."""
UNKNOWN_INDEX = -1  # a value's position when only the data knows it: `validate --no-data`, which returns no Plan


@dataclass(frozen=True)
class CompileContext:
    """The located config being compiled, where its problems collect (one mutable `Problems`, shared on purpose so one
    run reports every error), the folder its relative paths start from and what it may read and write."""

    document: Document
    problems: Problems
    config_dir: Path  # the config file's folder as named (not resolved): relative paths in the config start here
    confinement: Confinement
    xacro_budget: XacroBudget = field(default_factory=XacroBudget)  # the seconds every xacro expansion of this config shares
    opens_sources: bool = True  # False for `validate --no-data`: no source file is opened (a bag's /tf frames wait for the data)

    @property
    def data(self) -> dict[str, Any]:
        """The config as plain data (schema-valid)."""
        data: dict[str, Any] = self.document.data
        return data

    @property
    def source_names(self) -> frozenset[str]:
        """Every source the config defines, compiled or not: a broken source is reported once, not again by its users."""
        return frozenset(self.data["sources"])

    def where(self, *path: str | int) -> Where:
        return self.document.where(*path)

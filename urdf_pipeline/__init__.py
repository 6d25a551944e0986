"""urdf-pipeline: one schema-validated YAML file per robot setup becomes a validated Rerun recording."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

__version__ = "0.2.0"


def lazy_surface(package: str, names: Mapping[str, str]) -> Callable[[str], object]:
    """A package's `__getattr__` for its public names (name -> private module): a module is imported when one of its
    names is first used, so `validate` does not import Rerun, and the xacro child imports nothing it does not run."""

    def __getattr__(name: str) -> object:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    return __getattr__

"""The package itself: its version, each package's lazy surface, and pandas left out of the commands that never use it.

Here rather than in the root `__init__.py`, so that no stage imports upward into the package root."""

from __future__ import annotations

import ast
import importlib
import sys
from collections.abc import Callable
from pathlib import Path

__version__ = "0.3.0"  # the one place it is written (pyproject reads it)


def lazy_surface(package: str, init_file: str) -> tuple[list[str], Callable[[str], object]]:
    """A package's `__all__` and lazy `__getattr__`, from its one list of public names: the imports under
    `if TYPE_CHECKING:` in its `__init__.py` (`init_file`), which type checkers and editors read as written. A name's
    module is imported when the name is first used, so `validate` does not import Rerun, and the xacro child imports
    nothing it does not run. (Scientific Python's SPEC 1, `lazy_loader.attach_stub`, without a separate stub file.)"""
    names = surface_imports(Path(init_file).read_text(encoding="utf-8"))

    def __getattr__(name: str) -> object:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    return list(names), __getattr__


def surface_imports(source: str) -> dict[str, str]:
    """Public name -> the package's module that defines it, from the `from .MODULE import NAME` lines of the
    source's top-level `if TYPE_CHECKING:` block."""
    names: dict[str, str] = {}
    for node in ast.parse(source).body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for statement in node.body:
                assert isinstance(statement, ast.ImportFrom) and statement.level == 1 and statement.module, (
                    "a package surface lists `from .module import name` lines only"
                )
                names.update({alias.asname or alias.name: statement.module for alias in statement.names})
    return names


class PandasLeftOut:
    """A finder that says pandas is absent: pyarrow imports pandas at its first array only to ask whether the input is
    a pandas object. `cli.main` installs it for the commands that never need pandas, and a local worker process when
    the run's own process left pandas out."""

    @staticmethod
    def find_spec(name: str, path: object = None, target: object = None) -> None:
        if name == "pandas" or name.startswith("pandas."):
            raise ImportError("urdf-pipeline leaves pandas out of this command (nothing in it uses pandas)")

    @staticmethod
    def installed() -> bool:
        return any(isinstance(finder, PandasLeftOut) for finder in sys.meta_path)

"""The Python API (`urdf_pipeline.load`, `run`, `log`, `forward_kinematics`): the last stage, beside the command
line. May import every stage before it.

The names below are the package's public surface; `urdf_pipeline/__init__.py` re-exports them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .calls import ConfigError, forward_kinematics, load, log, run

__all__ = ["ConfigError", "forward_kinematics", "load", "log", "run"]

__getattr__ = lazy_surface(__name__, dict.fromkeys(__all__, "calls"))

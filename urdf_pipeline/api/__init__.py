"""The Python API (`urdf_pipeline.load`, `run`, `log`, `forward_kinematics`, `live`), beside the command line.

The names below are the package's public surface; `urdf_pipeline/__init__.py` re-exports them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .calls import ConfigError, forward_kinematics, live, load, log, run

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

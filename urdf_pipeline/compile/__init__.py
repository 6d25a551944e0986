"""Located config -> frozen Plan: robots, joint mapping and units, edges and the frame graph, sources and
segments. Everything that needs the URDF is checked here, before anything is written."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .compiler import FROM_CONFIG, FROM_LIVE_DATA, FROM_STREAM, Compiled, NameSource, check_config, compile_config, compile_document
    from .temporal_edges import describe_temporal_edge
    from .trails import source_timelines
    from .units import ANGULAR_UNITS, FACTORS, LINEAR_UNITS, UNIT_NAMES, bigger_unit, corrected, reaches, turn, unit_fits, unit_hint, within

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

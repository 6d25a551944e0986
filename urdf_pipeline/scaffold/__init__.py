"""`init`: a config scaffolded from a URDF (any form `run` accepts) and, optionally, a source's names and a sample of
its values; and the schema file `schema -o` writes beside the configs. It sits after `review/` because it asks check
(through review's surface) which unit each joint's sampled values are in.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .init_command import init_config, schema_reference, write_schema
    from .init_urdf import urdf_argument

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

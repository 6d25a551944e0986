"""The config as written: YAML with a location for every key, the JSON Schema, sidecar edge files, the format
templates a config or a dataset's metadata supplies, and the generated reference."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .document import MAX_BYTES, Document, format_path, load_document, parse_document
    from .schema import SCHEMA_RESOURCE, require_schema_valid, schema_text, validate_document
    from .sidecar import EdgeSpec, expand_edge_specs
    from .templates import Placeholder, Template, checked_template

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

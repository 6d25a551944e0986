"""Stage 1, the config as written: YAML with a location for every key, the JSON Schema, sidecar edge files, and the
generated reference. May import: the top-level base (errors, plan, confine). Knows nothing of URDFs or data.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .document import MAX_BYTES, Document, format_path, load_document, parse_document
    from .schema import SCHEMA_RESOURCE, require_schema_valid, schema_text, validate_document
    from .sidecar import EdgeSpec, expand_edge_specs

__all__ = [
    "MAX_BYTES",
    "Document",
    "EdgeSpec",
    "SCHEMA_RESOURCE",
    "expand_edge_specs",
    "format_path",
    "load_document",
    "parse_document",
    "require_schema_valid",
    "schema_text",
    "validate_document",
]

__getattr__ = lazy_surface(
    __name__,
    {
        "MAX_BYTES": "document",
        "Document": "document",
        "EdgeSpec": "sidecar",
        "SCHEMA_RESOURCE": "schema",
        "expand_edge_specs": "sidecar",
        "format_path": "document",
        "load_document": "document",
        "parse_document": "document",
        "require_schema_valid": "schema",
        "schema_text": "schema",
        "validate_document": "schema",
    },
)

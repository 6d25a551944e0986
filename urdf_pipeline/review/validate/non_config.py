"""`validate --skip-non-configs` (the pre-commit hook): which YAML files beside the configs are not configs at all
(sidecar edge files, ROS parameters). The rule is conservative, so that a config with a typo still fails."""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

from ...config import load_document, schema_text
from ...errors import UserError, closest, listing


@lru_cache(maxsize=1)
def config_keys() -> tuple[str, ...]:
    """The config's top-level keys, as the schema names them."""
    return tuple(json.loads(schema_text())["properties"])


def not_a_config(path: Path) -> str | None:
    """Why the file at `path` is not a urdf-pipeline config, or None when it is one (or may be one: validate it)."""
    try:
        data = load_document(path).data
    except UserError:
        return None  # unreadable or not YAML: validating it says where, at its line
    keys = config_keys()
    if isinstance(data, list):
        return "a top-level list, like a sidecar file of calibration edges"
    if isinstance(data, dict) and not any(key in keys or closest(str(key), keys) is not None for key in data):
        return f"a mapping with none of a config's top-level keys ({listing(list(keys))})"
    return None

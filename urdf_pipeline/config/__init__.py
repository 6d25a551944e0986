"""Stage 1, the config as written: YAML with a location for every key, the JSON Schema, sidecar edge files, and the
generated reference. May import: the top-level base (errors, plan, confine). Knows nothing of URDFs or data."""

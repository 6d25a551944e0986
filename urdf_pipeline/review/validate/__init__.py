"""`validate`: each config's problems as text, GitHub annotations or JSON, and the YAML files `--skip-non-configs` passes over."""

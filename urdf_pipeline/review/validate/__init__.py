"""`validate`: each config's problems as text, GitHub annotations or JSON (`annotations.py`), and which YAML files
`--skip-non-configs` passes over (`non_config.py`). Its names reach other packages through `review/__init__.py`."""

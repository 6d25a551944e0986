"""urdf-pipeline: one schema-validated YAML file per robot setup becomes a validated Rerun recording."""

__version__ = "0.2.0"

"""Stage 3, one segment of a Plan -> one recording: lazy Rerun streams (model, FK, edges), provenance, blueprint,
viewer, atomic writing. May import: the top-level base, config, urdf, sources, compile."""

"""Whole datasets: segments run on executors (local processes, Ray), manifest, fingerprints, catalog, summary,
signals. May import: everything below it (base, config, urdf, sources, compile, execute)."""

"""Stage 2, located config -> frozen Plan: robots, joint mapping and units, edges and the frame graph, sources and
segments. Everything that needs the URDF is checked here, before anything is written.
May import: the top-level base, config, urdf, sources."""

"""The review commands: check, plan (report), diff, init (scaffold), annotations for CI.
May import: everything below it (base, config, urdf, sources, compile, execute)."""

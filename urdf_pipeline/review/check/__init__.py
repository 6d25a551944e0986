"""`check`: which corrections put a sample of each mapped joint's values inside its URDF limits."""

"""`check`: which corrections put a sample of each mapped joint's values inside its URDF limits (`check_joints.py`),
from the candidates and their cost (`check_candidates.py`). Its names reach other packages through
`review/__init__.py`."""

"""`dir(urdf_pipeline)` is the Python API and `__version__`: what a notebook's completion offers, whatever modules of
the package have been imported."""

from __future__ import annotations

import subprocess
import sys

import urdf_pipeline

API = ["ConfigError", "LiveView", "Plan", "RobotKinematics", "forward_kinematics", "live", "load", "log", "run"]


def test_dir_is_the_api_and_the_version() -> None:
    assert sorted(urdf_pipeline.__all__) == API
    assert dir(urdf_pipeline) == sorted([*API, "__version__"])
    assert all(getattr(urdf_pipeline, name) is not None for name in API)


def test_dir_stays_the_api_once_the_package_modules_are_imported() -> None:
    code = "import urdf_pipeline, urdf_pipeline.cli, urdf_pipeline.errors; print(' '.join(dir(urdf_pipeline)))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == sorted([*API, "__version__"])

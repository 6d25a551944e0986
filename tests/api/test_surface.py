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


def test_the_docs_write_each_calls_signature_as_it_is() -> None:
    """docs/python-api.md (and docs/live.md for `live`) write each call's parameters with their defaults: the same as
    the function's signature, so a reader is never told a default the code does not have."""
    import inspect
    import re
    from pathlib import Path

    docs = Path(__file__).resolve().parents[2] / "docs"
    pages = {page: " ".join((docs / page).read_text(encoding="utf-8").split()) for page in ("python-api.md", "live.md")}
    for name in ("load", "run", "log", "forward_kinematics", "live"):
        signature = inspect.signature(getattr(urdf_pipeline, name))
        for page, text in pages.items():
            for written in re.findall(rf"`{name}\(([^`]*?)\)(?: -> [^`]*)?`", text):
                for part in (p.strip() for p in written.split(",")):
                    if "=" in part and part not in ("*", "**options"):
                        key, default = (s.strip() for s in part.split("=", 1))
                        assert key in signature.parameters, f"{page}: {name}() has no parameter {key}"
                        assert repr(signature.parameters[key].default).replace("'", '"') == default, (
                            f"{page}: {name}({key}={default}) but the code's default is {signature.parameters[key].default!r}"
                        )

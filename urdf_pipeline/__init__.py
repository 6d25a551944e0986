"""urdf-pipeline: one schema-validated YAML file per robot setup becomes a validated Rerun recording.

The Python API, for notebooks and scripts (see the README's "Python API"):

    plan = urdf_pipeline.load("configs/demo.yaml")           # compile and validate: a frozen Plan
    urdf_pipeline.run("configs/demo.yaml", jobs=2)            # what `urdf-pipeline run` does; the written paths
    urdf_pipeline.log("configs/demo.yaml", recording=rec)     # model, FK and edges into your RecordingStream
    fk = urdf_pipeline.forward_kinematics(plan)               # {robot: RobotKinematics}: links x rows poses

Every call raises `urdf_pipeline.ConfigError` with the command line's located messages (`error.lines()`).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping

__version__ = "0.3.0"


def lazy_surface(package: str, names: Mapping[str, str]) -> Callable[[str], object]:
    """A package's `__getattr__` for its public names (name -> private module): a module is imported when one of its
    names is first used, so `validate` does not import Rerun, and the xacro child imports nothing it does not run."""

    def __getattr__(name: str) -> object:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    return __getattr__


class PandasLeftOut:
    """A finder that says pandas is absent. pyarrow imports pandas, when it is installed (rerun-sdk[catalog], LeRobot),
    at its first array only to ask whether the input is a pandas object: 0.2-0.4 s of a 1.4 s demo run, for nothing
    the pipeline uses. `cli.main` installs it for the commands that never need pandas (not `run --catalog`, whose
    client may, nor `--executor ray`) and removes it when the command returns; a local worker process installs it
    when the run's own process left pandas out."""

    @staticmethod
    def find_spec(name: str, path: object = None, target: object = None) -> None:
        if name == "pandas" or name.startswith("pandas."):
            raise ImportError("urdf-pipeline leaves pandas out of this command (nothing in it uses pandas)")

    @staticmethod
    def installed() -> bool:
        return any(isinstance(finder, PandasLeftOut) for finder in sys.meta_path)


API = {
    "ConfigError": "api",
    "Plan": "plan",
    "RobotKinematics": "execute",
    "forward_kinematics": "api",
    "load": "api",
    "log": "api",
    "run": "api",
}
__all__ = ["PandasLeftOut", "__version__", "lazy_surface", *API]
__getattr__ = lazy_surface(__name__, API)  # nothing heavy is imported until a name is used

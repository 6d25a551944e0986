"""urdf-pipeline: one schema-validated YAML file per robot setup becomes a validated Rerun recording.

The Python API, for notebooks and scripts (docs/python-api.md):

    plan = urdf_pipeline.load("configs/demo.yaml")           # compile and validate: a frozen Plan
    urdf_pipeline.run("configs/demo.yaml", jobs=2)            # what `urdf-pipeline run` does; the written paths
    urdf_pipeline.log("configs/demo.yaml", recording=rec)     # model, FK and edges into your RecordingStream
    fk = urdf_pipeline.forward_kinematics(plan)               # {robot: RobotKinematics}: links x rows poses
    with urdf_pipeline.live("configs/arm.yaml") as view:       # a live view for a control loop (spawns a viewer)
        view.push(q)                                          # one sample, in the source's names order

Every call raises `urdf_pipeline.ConfigError` with the command line's located messages (`error.lines()`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .package import __version__ as __version__
from .package import lazy_surface

if TYPE_CHECKING:  # the public API, the one list: lazy_surface reads these lines
    from .api import ConfigError, forward_kinematics, live, load, log, run
    from .execute import RobotKinematics
    from .live_views import LiveView
    from .plan import Plan

if not TYPE_CHECKING:  # nothing heavy is imported until a name is used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

    def __dir__() -> list[str]:
        """`dir(urdf_pipeline)` is the Python API (and `__version__`), not the package's modules."""
        return sorted([*__all__, "__version__"])

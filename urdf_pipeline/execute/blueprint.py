"""The run's blueprint: a 3D view of the whole scene and one per robot, for the config's application id (and, with
`output.joint_series`, a time series view per driven robot beside them).

It is written once per run as `<config stem>.rbl` beside the outputs (open it in the viewer with the recordings)
and sent with every segment by `run --spawn` / `--connect`. It is not inside each .rrd: ChunkStore.write_rrd writes
one store, and writing through a RecordingStream instead (which can add a blueprint store) leaks 1.7-3.5 MB of
memory per stream in rerun-sdk 0.41 and doubles the time per layer, so a worker writing a dataset would grow without bound.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..plan import Plan, RobotPlan
from .joint_series import plotted_robots, series_entity
from .trail_stream import trail_time_ranges
from .writer import write_file_atomically

if TYPE_CHECKING:
    import rerun.blueprint as rrb

SCENE_VIEW = "scene"
PLOT_SUFFIX = " joints"  # a robot's time series view: "arm joints"


def recording_blueprint(plan: Plan) -> rrb.Blueprint:
    """The 3D views as tabs; with `output.joint_series`, beside them a column of time series views, one per driven
    robot, so a jump in a plot and the pose at that time are seen together (the time cursor is shared)."""
    import rerun.blueprint as rrb

    ranges = trail_time_ranges(plan.trails)  # `trails:`: the views show each trail's window before the time cursor
    views = [rrb.Spatial3DView(origin="/", name=SCENE_VIEW, time_ranges=ranges)]
    views += [rrb.Spatial3DView(origin=robot.entity_path_prefix, name=robot.key, time_ranges=ranges) for robot in plan.robots]
    spatial = rrb.Tabs(*views)
    plotted = _plotted(plan)
    if not plotted:
        return rrb.Blueprint(spatial, collapse_panels=False)
    plots = [rrb.TimeSeriesView(origin=series_entity(robot), name=f"{robot.key}{PLOT_SUFFIX}") for robot in plotted]
    return rrb.Blueprint(rrb.Horizontal(spatial, rrb.Vertical(*plots), column_shares=[3, 2]), collapse_panels=False)


def _plotted(plan: Plan) -> tuple[RobotPlan, ...]:
    return plotted_robots(plan.robots) if plan.dataset.joint_series else ()


def blueprint_path(plan: Plan) -> Path:
    return plan.dataset.manifest.parent / f"{plan.config_path.stem}.rbl"


def blueprint_key(plan: Plan) -> str:
    """What the blueprint is made of (the pipeline's version, the application id, the robots' views): the manifest
    keeps it, so a run whose blueprint is unchanged does not write it again."""
    import hashlib
    import json

    from ..package import __version__

    parts: list[object] = [__version__, plan.application_id, [[r.key, r.entity_path_prefix] for r in plan.robots]]
    plotted = _plotted(plan)
    if plotted:  # only then: the key of a blueprint without plots is as before
        parts.append({"joint_series": [r.key for r in plotted]})
    if plan.trails:  # only then, as above
        parts.append({"trails": [[t.timelines, t.window, t.window_unit] for t in plan.trails]})
    return hashlib.sha256(json.dumps(parts).encode()).hexdigest()


def write_blueprint(plan: Plan) -> Path:
    blueprint = recording_blueprint(plan)
    return write_file_atomically(blueprint_path(plan), lambda partial: blueprint.save(plan.application_id, partial))

"""The blueprint every written recording carries: a 3D view of the whole scene and one per robot.

It travels in the .rrd beside the data (a blueprint store of the same application id), so a layer added to an
existing recording (the split layout's forward kinematics on a base episode) still opens with 3D views.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .plan import Plan

if TYPE_CHECKING:
    import rerun.blueprint as rrb

SCENE_VIEW = "scene"


def recording_blueprint(plan: Plan) -> rrb.Blueprint:
    import rerun.blueprint as rrb

    views = [rrb.Spatial3DView(origin="/", name=SCENE_VIEW)]
    views += [rrb.Spatial3DView(origin=robot.entity_path_prefix, name=robot.key) for robot in plan.robots]
    return rrb.Blueprint(rrb.Tabs(*views), collapse_panels=False)

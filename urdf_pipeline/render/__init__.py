"""Pictures drawn by the real Rerun viewer (headless): `snapshot` of written recordings, `plan --render` and
`diff --render` of plans at their rest pose. May import: everything below it (base, config, urdf, sources, compile,
execute, dataset); it uses none of execute's or dataset's modules, only Rerun and the plan.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .headless_viewer import NO_RENDERER, Size
    from .plan_pictures import DEFAULT_SIZE, Picture, announce, render_diff, render_plan
    from .segment_pictures import SCENE, SnapshotRequest, snapshot

__all__ = [
    "DEFAULT_SIZE",
    "NO_RENDERER",
    "SCENE",
    "Picture",
    "Size",
    "SnapshotRequest",
    "announce",
    "render_diff",
    "render_plan",
    "snapshot",
]

__getattr__ = lazy_surface(
    __name__,
    {
        "DEFAULT_SIZE": "plan_pictures",
        "NO_RENDERER": "headless_viewer",
        "SCENE": "segment_pictures",
        "Picture": "plan_pictures",
        "Size": "headless_viewer",
        "SnapshotRequest": "segment_pictures",
        "announce": "plan_pictures",
        "render_diff": "plan_pictures",
        "render_plan": "plan_pictures",
        "snapshot": "segment_pictures",
    },
)

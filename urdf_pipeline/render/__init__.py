"""Pictures drawn by the real Rerun viewer (headless): `snapshot` of written recordings, `plan --render` and
`diff --render` of plans at their rest pose.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .camera import Camera
    from .headless_viewer import NO_RENDERER, Size
    from .plan_pictures import DEFAULT_SIZE, DiffNames, Picture, announce, render_diff, render_plan, scene_camera
    from .scene import rest_values, scene_chunks, shared_values
    from .segment_pictures import SCENE, SnapshotRequest, snapshot

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

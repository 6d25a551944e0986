"""The camera that frames plans at their rest pose (scene.py's chunks), for the web viewer's blueprint of
`plan --html` and `diff --html`: the pictures' three-quarter camera (camera.framing), one for every scene given, so
old and new are seen from the same eye."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..plan import Plan
from .camera import Camera, framing
from .frames import read_transforms
from .plan_pictures import robot_frames
from .scene import REST_POSE

if TYPE_CHECKING:
    from rerun.chunk import Chunk


def scene_camera(scenes: Sequence[tuple[Plan, Sequence[Chunk]]], width: int, height: int) -> Camera:
    """One camera at which every robot link of every (plan, its scene_chunks) at the rest pose fits a `width` x
    `height` view."""
    rest = np.zeros(1, np.int64)
    points = [
        read_transforms(chunks, REST_POSE).positions(plan.root_frame, robot_frames(plan.robots), rest).reshape(-1, 3)
        for plan, chunks in scenes
    ]
    return framing(np.concatenate(points), width, height)

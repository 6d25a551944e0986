"""Where the picture's camera goes: a fixed three-quarter view, as close as it can be with every link in the picture.

The view direction is fixed (in front of and to the right of a robot facing +x, from above, z up), so pictures of
one robot are comparable. Along it, the link positions (all of them, over every time pictured or the whole
segment) are boxed in the view's own axes: the box's middle is what the camera looks at, and the distance is the
smallest at which every link origin, padded by LINK_PADDING for the meshes around it, lies within `FILL` of the half
field of view on both axes. The viewer's 3D eye has a fixed vertical field of view of 55 degrees (measured with
rerun-sdk 0.41: a square of known size at a known distance); the horizontal one follows the picture's aspect.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FIELD_OF_VIEW_Y = math.radians(55.0)
FILL = 0.88  # share of the half field of view the padded links may reach: the rest is the margin
AZIMUTH = math.radians(-50.0)  # from +x towards -y
ELEVATION = math.radians(28.0)
UP = (0.0, 0.0, 1.0)  # URDF frames are z-up (REP 103); the recordings set no other up axis
LINK_PADDING = 0.12  # metres around a link origin: the meshes reach beyond the frames they hang on


@dataclass(frozen=True)
class Camera:
    """An orbit eye: where it is, what it looks at, which way is up (the blueprint's EyeControls3D)."""

    position: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = UP


def _triple(values: np.ndarray) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def view_axes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right, up and forward of the fixed three-quarter view, in the root frame."""
    toward_camera = np.array([math.cos(ELEVATION) * math.cos(AZIMUTH), math.cos(ELEVATION) * math.sin(AZIMUTH), math.sin(ELEVATION)])
    forward = -toward_camera
    right = np.cross(forward, UP)
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


def framing(points: np.ndarray, width: int, height: int) -> Camera:
    """The three-quarter camera at which every point (N x 3, root frame; NaN rows left out) fits a `width` x
    `height` picture with a margin."""
    finite = points[np.isfinite(points).all(axis=1)]
    if not len(finite):
        raise ValueError("no link position to frame")
    right, up, forward = view_axes()
    axes = np.stack([right, up, forward])
    local = finite @ axes.T  # x right, y up, z away from the camera
    low, high = local.min(axis=0), local.max(axis=0)
    middle = (low + high) / 2
    target = middle @ axes
    x, y, depth = (local - middle).T
    tan_y = math.tan(FIELD_OF_VIEW_Y / 2) * FILL
    tan_x = math.tan(FIELD_OF_VIEW_Y / 2) * width / height * FILL
    # A point at depth offset d (along the view) is inside when |x| + pad <= tan_x * (D + d - pad).
    distance = float(
        max(
            ((np.abs(x) + LINK_PADDING) / tan_x - depth + LINK_PADDING).max(),
            ((np.abs(y) + LINK_PADDING) / tan_y - depth + LINK_PADDING).max(),
        )
    )
    distance = max(distance, float((high - low)[2]) / 2 + 3 * LINK_PADDING)  # never among the links
    return Camera(_triple(target - forward * distance), _triple(target))

"""Where the picture's camera goes: a fixed three-quarter view, as close as it can be with all of the robot in the picture.

The view direction is fixed (in front of and to the right of a robot facing +x, from above, z up), so pictures of
one robot are comparable. What must be in the picture is a set of balls (link origins, the corners of each visual's
box), to fit inside the picture less a margin of (1 - FILL) and less the caption band. In the view's own axes that is
a linear program with a closed-form answer: per axis, the two extreme points bound how close the camera may come, and
it sits midway between them sideways, so the robot fills FILL of the picture's width or height, whatever its size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FIELD_OF_VIEW_Y = math.radians(55.0)  # the viewer's 3D eye, fixed; the horizontal one follows the picture's aspect
FILL = 0.88  # share of the half picture (from its middle to an edge) the robot may reach: the rest is the margin
AZIMUTH = math.radians(-50.0)  # from +x towards -y
ELEVATION = math.radians(28.0)
UP = (0.0, 0.0, 1.0)  # URDF frames are z-up (REP 103); the recordings set no other up axis
LINK_PADDING = 0.02  # metres around a link origin (the box corners hold the meshes; this keeps a frame's axes whole)
NEAREST = 0.05  # metres: the camera stays at least this far in front of every point


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


def frame_bounds(width: int, height: int, band: int = 0) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the robot may be, as tangents of the angle off the view's axis: (left, right) and (bottom, top). The
    picture spans -1..1 of its half-size on each axis; the band takes its bottom `band` pixels."""
    tan_y = math.tan(FIELD_OF_VIEW_Y / 2)
    tan_x = tan_y * width / height
    margin = 1 - FILL
    bottom = -1 + 2 * min(max(band, 0), height * 0.45) / height + margin
    return (-FILL * tan_x, FILL * tan_x), (bottom * tan_y, FILL * tan_y)


def framing(points: np.ndarray, width: int, height: int, band: int = 0, radii: np.ndarray | float = LINK_PADDING) -> Camera:
    """The three-quarter camera at which every point (N x 3, root frame; NaN rows left out), each a ball of its radius,
    lies in a `width` x `height` picture above a `band` pixels high, with a margin; as close as that allows."""
    spheres = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(points),))
    keep = np.isfinite(points).all(axis=1) & np.isfinite(spheres)
    finite, radius = points[keep], np.abs(spheres[keep])
    if not len(finite):
        raise ValueError("no link position to frame")
    right, up, forward = view_axes()
    local = finite @ np.stack([right, up, forward]).T  # x right, y up, z away from the camera
    x_bounds, y_bounds = frame_bounds(width, height, band)
    depth, sideways = local[:, 2], []
    nearest = float((depth - radius).min()) - NEAREST
    for axis, (low, high) in enumerate((x_bounds, y_bounds)):
        # Inside: low <= (p - c) / (depth - c_z) <= high, for the ball's centre moved in by its radius.
        value = local[:, axis]
        lowest = float((value - high * depth + radius * math.hypot(1, high)).max())  # c - high * c_z >= this
        highest = float((value - low * depth - radius * math.hypot(1, low)).min())  # c - low * c_z <= this
        nearest = min(nearest, (highest - lowest) / (high - low))
        sideways.append((lowest, highest, low, high))
    camera_z = nearest
    camera_xy = [((lowest + high * camera_z) + (highest + low * camera_z)) / 2 for lowest, highest, low, high in sideways]
    position = camera_xy[0] * right + camera_xy[1] * up + camera_z * forward
    reach = max(float(np.median(depth)) - camera_z, NEAREST)
    return Camera(_triple(position), _triple(position + forward * reach))

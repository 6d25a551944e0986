"""The camera rule without a viewer: a fixed three-quarter view, every ball inside the picture's frame (the picture
less a margin, less the caption band), and as close as that allows: the tighter axis is filled from edge to edge."""

from __future__ import annotations

import math

import numpy as np
import pytest

from urdf_pipeline.render.camera import FIELD_OF_VIEW_Y, FILL, UP, Camera, frame_bounds, framing, view_axes
from urdf_pipeline.render.headless_viewer import Size


def _tangents(points: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each point's tangent off the view's axis, right and up, and its depth."""
    right, up, forward = view_axes()
    offset = points - np.asarray(camera.position)
    depth = offset @ forward
    return (offset @ right) / depth, (offset @ up) / depth, depth


def _pixels(points: np.ndarray, camera: Camera, width: int, height: int) -> np.ndarray:
    """Where each point lands in the picture, in pixels from its top left corner."""
    x, y, _ = _tangents(points, camera)
    tan_y = math.tan(FIELD_OF_VIEW_Y / 2)
    tan_x = tan_y * width / height
    return np.stack([(1 + x / tan_x) * width / 2, (1 - y / tan_y) * height / 2], axis=1)


def _cloud(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(500, 3)) * rng.uniform(0.02, 2.0, size=3) + rng.uniform(-3, 3, size=3)


@pytest.mark.parametrize("size", [(320, 240), (240, 400), (1024, 768)])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("band", [0, 40])
def test_every_point_lands_inside_the_frame_and_the_tighter_axis_is_filled(size: tuple[int, int], seed: int, band: int) -> None:
    points = _cloud(seed)
    camera = framing(points, *size, band=band, radii=0.0)
    assert camera.up == UP
    (left, right), (bottom, top) = frame_bounds(*size, band)
    x, y, depth = _tangents(points, camera)
    assert (depth > 0).all(), "every point in front of the camera"
    assert x.min() >= left - 1e-9 and x.max() <= right + 1e-9 and y.min() >= bottom - 1e-9 and y.max() <= top + 1e-9
    filled = max((x.max() - x.min()) / (right - left), (y.max() - y.min()) / (top - bottom))
    assert filled == pytest.approx(1.0, abs=1e-6), "the points touch both sides of the frame on one axis"
    rows = _pixels(points, camera, *size)[:, 1]
    assert rows.max() <= size[1] - band, "nothing lands in the caption band"


def test_a_ball_is_kept_inside_by_its_radius() -> None:
    points = _cloud(3)
    bare, padded = framing(points, 320, 240, radii=0.0), framing(points, 320, 240, radii=0.3)
    right, up, forward = view_axes()
    for camera, radius in ((bare, 0.0), (padded, 0.3)):
        (left, right_bound), (bottom, top) = frame_bounds(320, 240)
        offset = points - np.asarray(camera.position)
        depth = offset @ forward
        for axis, (low, high) in ((right, (left, right_bound)), (up, (bottom, top))):
            side = offset @ axis
            # distance from each centre to the frame's planes through the camera, at least the radius
            assert ((high * depth - side) / math.hypot(1, high) >= radius - 1e-9).all()
            assert ((side - low * depth) / math.hypot(1, low) >= radius - 1e-9).all()
    assert np.linalg.norm(np.subtract(padded.position, padded.target)) > 0


def test_the_view_is_the_same_three_quarter_direction_for_any_robot() -> None:
    small = framing(np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.5]]), 320, 240)
    large = framing(np.array([[5.0, 5.0, 0.0], [9.0, 6.0, 3.0]]), 320, 240)
    direction = [np.subtract(c.target, c.position) / np.linalg.norm(np.subtract(c.target, c.position)) for c in (small, large)]
    assert np.allclose(direction[0], direction[1]) and np.allclose(direction[0], view_axes()[2])
    assert direction[0][2] < -0.3 and direction[0][0] < 0 and direction[0][1] > 0, "from above, in front, to the right"


def test_a_small_robot_fills_the_picture_as_a_large_one_does() -> None:
    """A 20 cm arm and a 2 m one, the same shape: the same share of the picture, the camera ten times as far."""
    shape = _cloud(4)
    shape = (shape - shape.mean(axis=0)) / np.ptp(shape, axis=0).max()
    cameras = [framing(shape * scale, 1024, 768, band=60, radii=0.0) for scale in (0.2, 2.0)]
    spans = [np.ptp(_pixels(shape * scale, camera, 1024, 768), axis=0) for scale, camera in zip((0.2, 2.0), cameras, strict=True)]
    assert np.allclose(spans[0], spans[1], rtol=1e-6)
    assert max(spans[0][0] / 1024, spans[0][1] / 768) >= FILL * 0.75
    near, far = (np.linalg.norm(np.asarray(camera.position)) for camera in cameras)  # the shape is centred on the origin
    assert far == pytest.approx(10 * near, rel=1e-6)


def test_links_that_are_not_placed_are_left_out() -> None:
    points = np.array([[0.0, 0.0, 0.0], [np.nan, np.nan, np.nan], [0.0, 0.0, 1.0]])
    assert framing(points, 320, 240) == framing(points[[0, 2]], 320, 240)
    with pytest.raises(ValueError, match="no link position"):
        framing(np.full((2, 3), np.nan), 320, 240)


def test_a_single_link_is_framed_with_its_padding() -> None:
    camera = framing(np.zeros((1, 3)), 320, 240, radii=0.1)
    distance = np.linalg.norm(np.asarray(camera.position))
    assert 0.1 < distance < 1.0


@pytest.mark.parametrize("text", ["320x240", "1024X768", "16x8192"])
def test_sizes_parse(text: str) -> None:
    width, height = (int(v) for v in text.lower().split("x"))
    assert Size.parse(text) == Size(width, height)


@pytest.mark.parametrize("text", ["320", "x240", "0x240", "320x15", "9000x100", "a x b", "-3x4"])
def test_bad_sizes_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="WIDTHxHEIGHT"):
        Size.parse(text)

"""The camera rule without a viewer: a fixed three-quarter view, every padded link inside the picture with a margin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from urdf_pipeline.render.camera import FIELD_OF_VIEW_Y, FILL, LINK_PADDING, UP, framing, view_axes
from urdf_pipeline.render.headless_viewer import Size


def _image_coordinates(points: np.ndarray, camera, width: int, height: int) -> np.ndarray:
    """Where each point lands, as a share of the half field of view (|value| <= 1: inside the picture)."""
    right, up, forward = view_axes()
    offset = points - np.asarray(camera.position)
    depth = offset @ forward
    tan_y = math.tan(FIELD_OF_VIEW_Y / 2)
    return np.stack([(offset @ right) / depth / (tan_y * width / height), (offset @ up) / depth / tan_y], axis=1)


@pytest.mark.parametrize("size", [(320, 240), (240, 400), (1024, 768)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_point_lands_inside_the_picture_with_a_margin(size: tuple[int, int], seed: int) -> None:
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(500, 3)) * rng.uniform(0.05, 2.0, size=3) + rng.uniform(-3, 3, size=3)
    camera = framing(points, *size)
    assert camera.up == UP
    spots = _image_coordinates(points, camera, *size)
    assert np.abs(spots).max() <= FILL + 1e-9, "a link outside the margin"
    assert np.abs(spots).max() >= FILL * 0.6, "the links use a good part of the picture"


def test_the_view_is_the_same_three_quarter_direction_for_any_robot() -> None:
    small = framing(np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.5]]), 320, 240)
    large = framing(np.array([[5.0, 5.0, 0.0], [9.0, 6.0, 3.0]]), 320, 240)
    direction = [np.subtract(c.position, c.target) / np.linalg.norm(np.subtract(c.position, c.target)) for c in (small, large)]
    assert np.allclose(direction[0], direction[1])
    assert direction[0][2] > 0.3 and direction[0][0] > 0 and direction[0][1] < 0, "from above, in front, to the right"
    assert np.linalg.norm(np.subtract(large.position, large.target)) > np.linalg.norm(np.subtract(small.position, small.target))


def test_links_that_are_not_placed_are_left_out() -> None:
    points = np.array([[0.0, 0.0, 0.0], [np.nan, np.nan, np.nan], [0.0, 0.0, 1.0]])
    assert framing(points, 320, 240) == framing(points[[0, 2]], 320, 240)
    with pytest.raises(ValueError, match="no link position"):
        framing(np.full((2, 3), np.nan), 320, 240)


def test_a_single_link_is_framed_with_its_padding() -> None:
    camera = framing(np.zeros((1, 3)), 320, 240)
    distance = np.linalg.norm(np.subtract(camera.position, camera.target))
    assert LINK_PADDING < distance < 20 * LINK_PADDING


@pytest.mark.parametrize("text", ["320x240", "1024X768", "16x8192"])
def test_sizes_parse(text: str) -> None:
    width, height = (int(v) for v in text.lower().split("x"))
    assert Size.parse(text) == Size(width, height)


@pytest.mark.parametrize("text", ["320", "x240", "0x240", "320x15", "9000x100", "a x b", "-3x4"])
def test_bad_sizes_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="WIDTHxHEIGHT"):
        Size.parse(text)

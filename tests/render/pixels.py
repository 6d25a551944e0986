"""What a picture shows, for the tests: the robot is what is bright against the viewer's dark background and grid, or
(`differing`) what differs from the background drawn by the same camera with nothing in the view."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from urdf_pipeline.render.captions import band_height
from urdf_pipeline.render.headless_viewer import Size

BRIGHT = 100  # grey level: the background is ~13 and the grid lines stay under ~70; lit meshes are far above
DIFFERENT = 24  # a channel this far from the background drawn by the same camera is the robot's (or an axis')


def grey(picture: Path | bytes) -> np.ndarray:
    source = io.BytesIO(picture) if isinstance(picture, bytes) else picture
    with Image.open(source) as image:
        return np.asarray(image.convert("L"), dtype=np.int16)


@dataclass(frozen=True)
class Robot:
    """The bright pixels: their share of the picture, and their bounding box as fractions of width and height."""

    share: float
    left: float
    right: float
    top: float
    bottom: float

    @property
    def width(self) -> float:
        return self.right - self.left

    @property
    def height(self) -> float:
        return self.bottom - self.top


def robot(picture: Path | bytes, lines: int = 2) -> Robot:
    """The bright pixels above the caption band (of `lines` lines: its text is bright too)."""
    pixels = grey(picture)
    mask = pixels > BRIGHT
    mask[mask.shape[0] - band_height(Size(mask.shape[1], mask.shape[0]), lines) :] = False
    assert mask.any(), "nothing bright in the picture: no robot drawn"
    rows, columns = np.nonzero(mask)
    height, width = mask.shape
    return Robot(float(mask.mean()), columns.min() / width, (columns.max() + 1) / width, rows.min() / height, (rows.max() + 1) / height)


def differing(picture: Path | bytes, background: Path | bytes, band: int = 0) -> Robot:
    """What differs from the background drawn by the same camera (the robot, its frames' axes), above the caption
    band: its share of the picture and its bounding box, as fractions of the whole picture's width and height."""
    pixels, empty = rgb(picture), rgb(background)
    mask = np.abs(pixels - empty).max(axis=2) > DIFFERENT
    height, width = mask.shape
    mask[height - band :] = False
    assert mask.any(), "nothing differs from the background: no robot drawn"
    rows, columns = np.nonzero(mask)
    return Robot(float(mask.mean()), columns.min() / width, (columns.max() + 1) / width, rows.min() / height, (rows.max() + 1) / height)


def rgb(picture: Path | bytes) -> np.ndarray:
    source = io.BytesIO(picture) if isinstance(picture, bytes) else picture
    with Image.open(source) as image:
        return np.asarray(image.convert("RGB"), dtype=np.int16)


def assert_framed(picture: Path | bytes, margin: float = 0.02, share: float = 0.01, extent: float = 0.25) -> Robot:
    """All of the robot inside the picture with a margin on every side, covering a real share of it."""
    found = robot(picture)
    assert found.left >= margin and found.top >= margin, f"robot at the picture's left or top edge: {found}"
    assert found.right <= 1 - margin and found.bottom <= 1 - margin, f"robot at the picture's right or bottom edge: {found}"
    assert found.share >= share, f"robot covers too little of the picture: {found}"
    assert max(found.width, found.height) >= extent, f"robot too small in the picture: {found}"
    return found

"""What Rerun's web viewer shows, for the browser tests: the robot is what differs from the 3D view's background in the
middle of the page (the viewer's panels stay at its edges in a 1024x768 tab)."""

from __future__ import annotations

import io
import time

import numpy as np
from PIL import Image

from .devtools import Page

ROBOT_SECONDS = 300.0  # generous: the wasm compiles in 45-60 s on 2 busy cores, then the meshes load and draw
DIFFERENT = 60  # summed |RGB| difference from the view's background that counts as drawn
ROBOT_SHARE = 0.05  # of the page's centre, inside the 3D view: the demo's Panda covers about a fifth of it


def drawn_share(png: bytes) -> float:
    """The share of the page's centre whose colour differs from its most common one (the view's background): the
    robot's pixels; the grid's faint lines stay under the threshold."""
    with Image.open(io.BytesIO(png)) as image:
        pixels = np.asarray(image.convert("RGB"), dtype=np.int32)
    height, width, _ = pixels.shape
    centre = pixels[int(height * 0.25) : int(height * 0.65), int(width * 0.35) : int(width * 0.65)].reshape(-1, 3)
    colours, counts = np.unique(centre, axis=0, return_counts=True)
    background = colours[counts.argmax()]
    return float((np.abs(centre - background).sum(axis=1) > DIFFERENT).mean())


def wait_for_robot(page: Page, timeout: float = ROBOT_SECONDS) -> tuple[float, float]:
    """Once the viewer page (`viewer/index.html`, just opened) has started and draws a robot: the share of the centre
    it covers, and the seconds it took. AssertionError, with the page's console errors, after `timeout` seconds."""
    started = time.monotonic()

    def robot() -> float:
        share = drawn_share(page.screenshot())
        return share if share >= ROBOT_SHARE and page.evaluate("document.body.dataset.state") == "started" else 0.0

    share = page.wait_for(robot, timeout, f"the robot on the viewer's canvas (console errors: {page.console_errors()})", poll=1.0)
    return share, time.monotonic() - started

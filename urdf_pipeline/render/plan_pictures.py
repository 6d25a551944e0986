"""The pictures a reviewer sees: `plan --render` (the rest pose), `diff --render` (old and new at the same joint
values, one camera) and `snapshot` (a written recording at chosen times). One viewer per command draws them all."""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError
from ..plan import Plan, RobotPlan
from ..progress import say
from .camera import framing
from .frames import RecordedTransforms, read_transforms
from .headless_viewer import HeadlessViewer, Shot, Size, write_png
from .scene import AXES_ENTITY, REST_POSE, rest_values, scene_chunks, shared_values

DEFAULT_SIZE = Size(1024, 768)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class Picture:
    """One PNG written: what it shows ("scene", a robot key, "old", "frame_index 450") and where it is."""

    label: str
    path: Path


def robot_frames(robots: Sequence[RobotPlan]) -> list[str]:
    """The link frames of `robots`, prefixed as the recordings name them."""
    return [robot.frame_prefix + link for robot in robots for link in robot.links]


def view_contents(robots: Sequence[RobotPlan], whole_scene: bool) -> tuple[str, ...]:
    """What a picture's view holds: everything, or one robot's entities and the frames' axes."""
    if whole_scene:
        return ("/**",)
    return (*(f"{robot.entity_path_prefix}/**" for robot in robots), f"{AXES_ENTITY}/**")


def require_picture_path(path: Path) -> None:
    """A picture may replace an earlier picture, never another file."""
    if path.is_dir() or (path.exists() and _head(path) != PNG_MAGIC):
        raise UserError(f"{path} exists and is not a PNG picture: refusing to write over it")


def _head(path: Path) -> bytes:
    with open(path, "rb") as stream:
        return stream.read(len(PNG_MAGIC))


def _points(transforms: RecordedTransforms, root: str, robots: Sequence[RobotPlan], times: np.ndarray | None = None) -> np.ndarray:
    return transforms.positions(root, robot_frames(robots), times).reshape(-1, 3)


def render_plan(plan: Plan, folder: Path, size: Size = DEFAULT_SIZE) -> tuple[Picture, ...]:
    """The whole scene at rest, and each robot alone when there are several."""
    chunks = scene_chunks(plan, rest_values(plan))
    transforms = read_transforms(chunks, REST_POSE)
    views: list[tuple[str, tuple[RobotPlan, ...], bool]] = [("scene", plan.robots, True)]
    if len(plan.robots) > 1:
        views += [(robot.key, (robot,), False) for robot in plan.robots]
    paths = [folder / f"{plan.config_path.stem}.plan.{label}.png" for label, _, _ in views]
    for path in paths:
        require_picture_path(path)
    pictures = []
    with HeadlessViewer(size) as viewer:
        store = viewer.show(plan.application_id, "plan", chunks)
        for (label, robots, whole), path in zip(views, paths, strict=True):
            camera = framing(_points(transforms, plan.root_frame, robots, np.zeros(1, np.int64)), size.width, size.height)
            viewer.picture(store, Shot(camera, view_contents(robots, whole), REST_POSE, 0), path)
            pictures.append(Picture(label, path))
    return tuple(pictures)


def render_diff(old: Plan, new: Plan, folder: Path, stem: str, size: Size = DEFAULT_SIZE) -> tuple[Picture, ...]:
    """Old and new at the same joint values, from one camera that frames both, and the two side by side."""
    values = shared_values(old, new)
    chunks = {"old": scene_chunks(old, values), "new": scene_chunks(new, values)}
    plans = {"old": old, "new": new}
    rest = np.zeros(1, np.int64)
    points = np.concatenate(
        [_points(read_transforms(chunks[side], REST_POSE), plans[side].root_frame, plans[side].robots, rest) for side in plans]
    )
    camera = framing(points, size.width, size.height)
    paths = {side: folder / f"{stem}.diff.{side}.png" for side in plans}
    both = folder / f"{stem}.diff.png"
    for path in [*paths.values(), both]:
        require_picture_path(path)
    pngs = {}
    with HeadlessViewer(size) as viewer:
        for side in plans:
            store = viewer.show(new.application_id, f"diff_{side}", chunks[side])
            viewer.picture(store, Shot(camera, ("/**",), REST_POSE, 0), paths[side])
            pngs[side] = paths[side].read_bytes()
    write_png(both, side_by_side([("old", pngs["old"]), ("new", pngs["new"])]))
    return (Picture("old", paths["old"]), Picture("new", paths["new"]), Picture("side by side", both))


def side_by_side(labelled: Sequence[tuple[str, bytes]]) -> bytes:  # Pillow >= 10.1: load_default(size=...)
    """PNGs next to each other, 8 pixels apart, each with its label in its top left corner."""
    from PIL import Image, ImageDraw, ImageFont

    images = [Image.open(io.BytesIO(png)).convert("RGB") for _, png in labelled]
    font = ImageFont.load_default(size=max(12, images[0].height // 32))
    gap = 8
    out = Image.new("RGB", (sum(i.width for i in images) + gap * (len(images) - 1), max(i.height for i in images)), (60, 60, 60))
    left = 0
    for (label, _), image in zip(labelled, images, strict=True):
        out.paste(image, (left, 0))
        ImageDraw.Draw(out).text((left + 10, 8), label, fill=(255, 210, 80), font=font)
        left += image.width + gap
    buffer = io.BytesIO()
    out.save(buffer, format="PNG")
    return buffer.getvalue()


def announce(pictures: Sequence[Picture], seconds: float) -> None:
    say(f"{len(pictures)} picture(s) drawn by the Rerun viewer in {seconds:.1f} s")

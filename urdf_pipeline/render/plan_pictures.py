"""The pictures a reviewer sees: `plan --render` (the rest pose), `diff --render` (old and new at the same joint
values, one camera, side by side and the old one as a ghost over the new) and `snapshot` (a written recording at
chosen times). One viewer per command draws them all; each picture gets its caption band (captions.py)."""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import UserError, shown
from ..logs import say
from ..plan import Plan, RobotPlan
from .camera import LINK_PADDING, Camera, framing
from .captions import band_height, burn_caption, changes_caption, ghost_over
from .frames import RecordedTransforms, read_transforms
from .headless_viewer import HeadlessViewer, Shot, Size, png_bytes, write_png
from .mesh_bounds import GeometryBoxes, geometry_boxes
from .scene import AXES_ENTITY, AXIS_LENGTH, REST_POSE, JointValues, rest_values, scene_chunks, shared_values

if TYPE_CHECKING:
    from rerun.chunk import Chunk

DEFAULT_SIZE = Size(1024, 768)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
NOTHING = ("/__urdf_pipeline_nothing/**",)  # a view's contents that match no entity: the background alone
REST = np.zeros(1, np.int64)


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


def scene_camera(scenes: Sequence[tuple[Plan, Sequence[Chunk]]], width: int, height: int) -> Camera:
    """The pictures' camera for the web viewer of `plan --html` and `diff --html`: every robot link of every (plan, its
    scene_chunks) at rest fits a `width` x `height` view, so old and new are seen from the same eye."""
    points = [
        read_transforms(chunks, REST_POSE).positions(plan.root_frame, robot_frames(plan.robots), REST).reshape(-1, 3)
        for plan, chunks in scenes
    ]
    return framing(np.concatenate(points), width, height)


def require_picture_path(path: Path) -> None:
    """A picture may replace an earlier picture, never another file."""
    if path.is_dir() or (path.exists() and _head(path) != PNG_MAGIC):
        raise UserError(f"{path} exists and is not a PNG picture: refusing to write over it")


def _head(path: Path) -> bytes:
    with open(path, "rb") as stream:
        return stream.read(len(PNG_MAGIC))


def extent(
    transforms: RecordedTransforms,
    boxes: GeometryBoxes,
    root: str,
    robots: Sequence[RobotPlan],
    whole_scene: bool,
    times: np.ndarray | None = None,
    axes: Sequence[str] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """What a picture must hold, as points and their radii: the robots' link origins, the corners of their visuals'
    boxes (every visual in the whole scene) and the frames whose axes are drawn, at `times` (default: the recording's)."""
    if times is None:
        times = transforms.sampled_times()
    links = transforms.positions(root, robot_frames(robots), times).reshape(-1, 3)
    shown_boxes = boxes if whole_scene else boxes.under(robot.entity_path_prefix for robot in robots)
    corners = shown_boxes.world(transforms.poses(root, shown_boxes.frames, times))
    frames = transforms.positions(root, axes, times).reshape(-1, 3)
    points = np.concatenate([links, corners, frames])
    radii = np.concatenate([np.full(len(links), LINK_PADDING), np.zeros(len(corners)), np.full(len(frames), AXIS_LENGTH)])
    return points, radii


@dataclass(frozen=True)
class RestScene:
    """A plan drawn at rest (scene.py): its chunks, the transforms and visuals' boxes read from them once."""

    plan: Plan
    chunks: list[Chunk]
    transforms: RecordedTransforms
    boxes: GeometryBoxes

    @staticmethod
    def of(plan: Plan, values: JointValues) -> RestScene:
        chunks = scene_chunks(plan, values)
        return RestScene(plan, chunks, read_transforms(chunks, REST_POSE), geometry_boxes(chunks))

    def extent(self, robots: Sequence[RobotPlan], whole_scene: bool) -> tuple[np.ndarray, np.ndarray]:
        """What a picture of `robots` must hold at rest; the frames' axes count in the whole scene."""
        plan = self.plan
        axes = sorted({plan.root_frame, *(e.child for e in plan.edges), *(e.child for e in plan.temporal_edges)}) if whole_scene else []
        return extent(self.transforms, self.boxes, plan.root_frame, robots, whole_scene, REST, axes)


def render_plan(plan: Plan, folder: Path, size: Size = DEFAULT_SIZE) -> tuple[Picture, ...]:
    """The whole scene at rest, and each robot alone when there are several; each captioned with the config."""
    scene = RestScene.of(plan, rest_values(plan))
    views: list[tuple[str, tuple[RobotPlan, ...], bool]] = [("scene", plan.robots, True)]
    if len(plan.robots) > 1:
        views += [(robot.key, (robot,), False) for robot in plan.robots]
    paths = [folder / f"{plan.config_path.stem}.plan.{label}.png" for label, _, _ in views]
    for path in paths:
        require_picture_path(path)
    band = band_height(size, 2)
    pictures = []
    with HeadlessViewer(size) as viewer:
        store = viewer.show(plan.application_id, "plan", scene.chunks)
        for (label, robots, whole), path in zip(views, paths, strict=True):
            points, radii = scene.extent(robots, whole)
            camera = framing(points, size.width, size.height, band, radii)
            png = viewer.draw(store, Shot(camera, view_contents(robots, whole), REST_POSE, 0))
            what = "the whole scene" if whole else f"robot {shown(label)}"
            write_png(path, burn_caption(png, [f"{shown(plan.config_path.name)} · rest pose", what], band))
            pictures.append(Picture(label, path))
    return tuple(pictures)


@dataclass(frozen=True)
class DiffNames:
    """How the diff's captions name the two configs (as the report does: `OLD`, `CONFIG@REV`), and its changes as
    short lines, the most telling first (moved edges, remapped joints)."""

    old: str
    new: str
    changes: tuple[str, ...] = ()


def render_diff(
    old: Plan, new: Plan, folder: Path, stem: str, size: Size = DEFAULT_SIZE, names: DiffNames | None = None
) -> tuple[Picture, ...]:
    """Old and new at the same joint values, from one camera that frames both: each alone, the two side by side, and
    the old one as a tinted ghost over the new one with what changed in its caption."""
    names = names or DiffNames(old.config_path.name, new.config_path.name)
    values = shared_values(old, new)
    scenes = {"old": RestScene.of(old, values), "new": RestScene.of(new, values)}
    extents = [scene.extent(scene.plan.robots, True) for scene in scenes.values()]
    ghost_caption = changes_caption(f"{shown(names.old)} (blue ghost) -> {shown(names.new)}", names.changes, size)
    band = band_height(size, len(ghost_caption))
    camera = framing(np.concatenate([p for p, _ in extents]), size.width, size.height, band, np.concatenate([r for _, r in extents]))
    paths = {side: folder / f"{stem}.diff.{side}.png" for side in ("old", "new", "overlay")}
    both = folder / f"{stem}.diff.png"
    for path in [*paths.values(), both]:
        require_picture_path(path)
    pngs = _draw_diff({side: scene.chunks for side, scene in scenes.items()}, new.application_id, camera, size)
    for side, name in (("old", names.old), ("new", names.new)):
        write_png(
            paths[side], burn_caption(pngs[side], [f"{side}: {shown(name)}", "rest pose, at the joint values both plans share"], band)
        )
    write_png(both, side_by_side([(side, paths[side].read_bytes()) for side in ("old", "new")]))
    write_png(paths["overlay"], burn_caption(ghost_over(pngs["new"], pngs["old"], pngs["background"]), ghost_caption, band))
    return (
        Picture("old", paths["old"]),
        Picture("new", paths["new"]),
        Picture("side by side", both),
        Picture("overlay", paths["overlay"]),
    )


def _draw_diff(chunks: dict[str, list[Chunk]], application_id: str, camera: Camera, size: Size) -> dict[str, bytes]:
    """Old, new and the background alone (what the ghost is told apart from), uncaptioned, from one camera."""
    pngs = {}
    with HeadlessViewer(size) as viewer:
        for side in ("old", "new"):
            store = viewer.show(application_id, f"diff_{side}", chunks[side])
            pngs[side] = viewer.draw(store, Shot(camera, ("/**",), REST_POSE, 0))
        pngs["background"] = viewer.draw(store, Shot(camera, NOTHING, REST_POSE, 0))
    return pngs


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
    return png_bytes(out)


def announce(pictures: Sequence[Picture], seconds: float) -> None:
    say(f"{len(pictures)} picture(s) drawn by the Rerun viewer in {seconds:.1f} s")

"""The framing on real pictures of the example robots, small and large, one arm and two: what differs from the
background drawn by the same camera spans at least half the picture's width or height, stays inside it, and stays
out of the caption band. One viewer for the module."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from urdf_pipeline import cli
from urdf_pipeline.compile import compile_config
from urdf_pipeline.plan import Plan, RobotPlan
from urdf_pipeline.render.camera import framing
from urdf_pipeline.render.captions import band_height
from urdf_pipeline.render.frames import read_transforms, transform_timelines
from urdf_pipeline.render.headless_viewer import HeadlessViewer, Shot
from urdf_pipeline.render.mesh_bounds import geometry_boxes
from urdf_pipeline.render.plan_pictures import NOTHING, RestScene, extent, view_contents
from urdf_pipeline.render.scene import REST_POSE, rest_values

from .conftest import SMALL
from .pixels import Robot, differing

pytestmark = pytest.mark.usefixtures("renderer")
BAND = band_height(SMALL, 2)
HALF = 0.5


def _assert_fills(picture: bytes, background: bytes, whole_scene: bool) -> Robot:
    """At least half the width or height, inside the picture; in the whole scene, nothing drawn in the band's rows."""
    found = differing(picture, background, BAND)
    assert max(found.width, found.height) >= HALF, f"the robot fills too little of the picture: {found}"
    assert found.left > 0 and found.top > 0 and found.right < 1, f"the robot is cut at an edge: {found}"
    if whole_scene:
        everything = differing(picture, background)
        assert everything.bottom <= 1 - BAND / SMALL.height, f"drawn where the caption goes: {everything}"
    return found


def _pair(viewer: HeadlessViewer, store: str, shot: Shot) -> tuple[bytes, bytes]:
    return viewer.draw(store, shot), viewer.draw(store, Shot(shot.camera, NOTHING, shot.timeline, shot.time))


@pytest.mark.parametrize(
    ("name", "view"),
    [("demo", "scene"), ("so101_dataset", "scene"), ("g1_held_joints", "scene"), ("aloha_bimanual", "scene"), ("aloha_bimanual", "left")],
)
def test_the_rest_pose_fills_the_picture(viewer: HeadlessViewer, examples_dir: Path, name: str, view: str) -> None:
    plan = compile_config(examples_dir / f"{name}.yaml")
    scene = RestScene.of(plan, rest_values(plan))
    whole = view == "scene"
    robots = plan.robots if whole else tuple(r for r in plan.robots if r.key == view)
    points, radii = scene.extent(robots, whole)
    camera = framing(points, SMALL.width, SMALL.height, BAND, radii)
    store = viewer.show(plan.application_id, f"plan_{name}", scene.chunks)
    _assert_fills(*_pair(viewer, store, Shot(camera, view_contents(robots, whole), REST_POSE, 0)), whole)


@pytest.fixture(scope="module")
def so101(examples_dir: Path) -> Path:
    assert cli.main(["run", str(examples_dir / "so101_lerobot.yaml"), "--jobs", "1"]) == 0
    return examples_dir / "so101_lerobot.yaml"


def _snapshot_pairs(viewer: HeadlessViewer, plan: Plan, robots: Sequence[RobotPlan], whole: bool) -> list[tuple[bytes, bytes]]:
    """The first and last row of the first segment, each framed on its own pose (as `snapshot` does)."""
    chunks = RrdReader(plan.segments[0].output).stream().to_chunks()
    (timeline,) = transform_timelines(chunks, [r.fk_entity for r in robots])[:1]
    transforms = read_transforms(chunks, timeline)
    boxes = geometry_boxes(chunks)
    store = viewer.show(plan.application_id, plan.segments[0].id, chunks)
    pairs = []
    for time in (int(transforms.times[0]), int(transforms.times[-1])):
        points, radii = extent(transforms, boxes, plan.root_frame, robots, whole, np.array([time]))
        camera = framing(points, SMALL.width, SMALL.height, BAND, radii)
        pairs.append(_pair(viewer, store, Shot(camera, view_contents(robots, whole), timeline, time)))
    return pairs


@pytest.mark.parametrize(
    ("name", "view"), [("demo", "scene"), ("bimanual_pandas", "scene"), ("bimanual_pandas", "right"), ("so101", "scene")]
)
def test_each_snapshot_pose_fills_its_picture(
    viewer: HeadlessViewer, examples_dir: Path, written: dict[str, Path], so101: Path, name: str, view: str
) -> None:
    """A robot that sweeps a metre over the segment (the so101's generated motion) still fills each picture."""
    plan = compile_config(so101 if name == "so101" else examples_dir / f"{name}.yaml")
    whole = view == "scene"
    robots = plan.robots if whole else tuple(r for r in plan.robots if r.key == view)
    for picture, background in _snapshot_pairs(viewer, plan, robots, whole):
        _assert_fills(picture, background, whole)

"""The real viewer, one for the module: the camera we set is the camera it draws with, and its own transform graph
places every URDF link under the root."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from urdf_pipeline.compile import compile_config
from urdf_pipeline.render.camera import Camera, framing
from urdf_pipeline.render.frames import read_transforms, transform_timelines
from urdf_pipeline.render.headless_viewer import HeadlessViewer, Shot
from urdf_pipeline.render.mesh_bounds import geometry_boxes
from urdf_pipeline.render.plan_pictures import extent, robot_frames

from .conftest import SMALL
from .pixels import assert_framed, grey, robot

pytestmark = pytest.mark.usefixtures("renderer")


@pytest.fixture(scope="module")
def demo(viewer: HeadlessViewer, examples_dir: Path, written: dict[str, Path]):
    plan = compile_config(examples_dir / "demo.yaml")
    chunks = RrdReader(written["demo"]).stream().to_chunks()
    (timeline,) = transform_timelines(chunks, [r.fk_entity for r in plan.robots])
    transforms = read_transforms(chunks, timeline)
    points, radii = extent(transforms, geometry_boxes(chunks), plan.root_frame, plan.robots, True)  # the whole segment
    camera = framing(points, SMALL.width, SMALL.height, radii=radii)
    store = viewer.show(plan.application_id, plan.segments[0].id, chunks)
    return store, timeline, camera


def _farther(camera: Camera, factor: float) -> Camera:
    target = np.asarray(camera.target)
    return Camera(tuple(target + (np.asarray(camera.position) - target) * factor), camera.target)  # type: ignore[arg-type]


def test_the_camera_set_is_the_camera_used(viewer: HeadlessViewer, demo) -> None:
    """Framed, the robot is inside the picture with a margin; from twice as far it is half as tall, where it was."""
    store, timeline, camera = demo
    near = viewer.draw(store, Shot(camera, ("/**",), timeline, 149))
    far = viewer.draw(store, Shot(_farther(camera, 2.0), ("/**",), timeline, 149))
    assert grey(near).shape == (SMALL.height, SMALL.width)
    framed, small = assert_framed(near), robot(far)
    assert 0.35 < small.height / framed.height < 0.65, (framed, small)
    assert abs((small.top + small.bottom) - (framed.top + framed.bottom)) / 2 < 0.2, "the same look target"
    again = viewer.draw(store, Shot(camera, ("/**",), timeline, 149))
    assert np.array_equal(grey(again), grey(near)), "the same camera and time draw the same picture"


@pytest.mark.parametrize("name", ["demo", "bimanual_pandas"])
def test_the_viewers_transform_graph_connects_every_link_to_the_root(
    viewer: HeadlessViewer, examples_dir: Path, written: dict[str, Path], name: str
) -> None:
    plan = compile_config(examples_dir / f"{name}.yaml")
    chunks = RrdReader(written[name]).stream().to_chunks()
    (timeline,) = transform_timelines(chunks, [r.fk_entity for r in plan.robots])
    times = read_transforms(chunks, timeline).times
    store = viewer.show(plan.application_id, plan.segments[0].id, chunks)
    graph = viewer.transform_graph(store, timeline, int(times[len(times) // 2]))
    parents: dict[str, set[str]] = {}
    for edge in graph["edges"]:
        parents.setdefault(edge["child"], set()).add(edge["parent"])
    links = robot_frames(plan.robots)
    assert len(links) > 10
    for link in links:
        frame, hops = link, 0
        while frame != plan.root_frame:
            assert len(parents.get(frame, ())) == 1, f"{link}: {frame} has parents {parents.get(frame)} in the viewer's graph"
            (frame,) = parents[frame]
            hops += 1
            assert hops < 100, f"{link}: a cycle"
    assert plan.root_frame not in parents, "the root has no parent"

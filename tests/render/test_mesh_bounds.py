"""What the visuals occupy (mesh_bounds.py), without a viewer: mesh files of each format written here, URDF primitives
streamed by Rerun's own URDF loader, and the example Panda's COLLADA meshes."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from rerun.urdf import UrdfTree

from urdf_pipeline.render.frames import read_transforms
from urdf_pipeline.render.mesh_bounds import FALLBACK_HALF_SIZE, geometry_boxes, mesh_box

TRIANGLE = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.1], [0.0, -0.2, 0.5]])


def _binary_stl(triangles: np.ndarray) -> bytes:
    body = b"".join(struct.pack("<12fH", 0, 0, 1, *triangle.reshape(-1), 0) for triangle in triangles)
    return b"\0" * 80 + struct.pack("<I", len(triangles)) + body


def _collada(up: str = "Z_UP", meter: float = 1.0, matrix: str = "1 0 0 0.5 0 1 0 0 0 0 1 0 0 0 0 1") -> bytes:
    positions = " ".join(str(v) for v in TRIANGLE.reshape(-1))
    return f"""<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="x" meter="{meter}"/><up_axis>{up}</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="g-pos"><float_array id="g-pos-array" count="9">{positions}</float_array>
      <technique_common><accessor source="#g-pos-array" count="3" stride="3"/></technique_common></source>
    <vertices id="g-vtx"><input semantic="POSITION" source="#g-pos"/></vertices>
    <triangles count="1"><input semantic="VERTEX" source="#g-vtx" offset="0"/><p>0 1 2</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s">
    <node id="camera"><matrix>1 0 0 7 0 1 0 7 0 0 1 7 0 0 0 1</matrix></node>
    <node id="n"><matrix>{matrix}</matrix><instance_geometry url="#g"/></node>
  </visual_scene></library_visual_scenes>
</COLLADA>""".encode()


def _assert_box(box, low, high) -> None:
    assert box is not None
    assert np.allclose(box[0], low, atol=1e-6) and np.allclose(box[1], high, atol=1e-6), box


def test_stl_binary_and_ascii() -> None:
    _assert_box(mesh_box(_binary_stl(TRIANGLE[None]), "model/stl"), TRIANGLE.min(axis=0), TRIANGLE.max(axis=0))
    ascii_stl = (
        "solid t\nfacet normal 0 0 1\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n" for x, y, z in TRIANGLE) + "endloop\nendfacet\n"
    )
    _assert_box(mesh_box(ascii_stl.encode(), "model/stl"), TRIANGLE.min(axis=0), TRIANGLE.max(axis=0))


def test_obj() -> None:
    text = "# a comment\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in TRIANGLE) + "vn 0 0 1\nf 1 2 3\n"
    _assert_box(mesh_box(text.encode(), "model/obj"), TRIANGLE.min(axis=0), TRIANGLE.max(axis=0))


def test_collada_follows_its_nodes_and_unit() -> None:
    """The instancing node's matrix moves the vertices; a node without geometry (a camera 7 m away) does not count."""
    _assert_box(mesh_box(_collada(), "model/vnd.collada+xml"), TRIANGLE.min(axis=0) + [0.5, 0, 0], TRIANGLE.max(axis=0) + [0.5, 0, 0])
    scaled = mesh_box(_collada(meter=0.001), "model/vnd.collada+xml")
    _assert_box(scaled, (TRIANGLE.min(axis=0) + [0.5, 0, 0]) / 1000, (TRIANGLE.max(axis=0) + [0.5, 0, 0]) / 1000)


def test_a_collada_file_not_z_up_counts_as_the_cube_around_its_farthest_vertex() -> None:
    box = mesh_box(_collada(up="Y_UP", matrix="1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"), "model/vnd.collada+xml")
    reach = np.linalg.norm(TRIANGLE, axis=1).max()
    _assert_box(box, [-reach] * 3, [reach] * 3)


def test_gltf_accessor_bounds_make_a_cube_that_holds_any_turn() -> None:
    document = {
        "accessors": [{"min": [-0.1, 0.0, -0.2], "max": [0.1, 0.4, 0.2]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0, "translation": [0.0, 0.1, 0.0]}],
    }
    text = json.dumps(document).encode()
    binary = b"glTF" + struct.pack("<II", 2, 20 + len(text)) + struct.pack("<I", len(text)) + b"JSON" + text
    reach = np.linalg.norm([0.1, 0.4, 0.2]) + 0.1
    for data, media in ((text, "model/gltf+json"), (binary, "model/gltf-binary")):
        _assert_box(mesh_box(data, media), [-reach] * 3, [reach] * 3)


@pytest.mark.parametrize(
    ("data", "media"),
    [
        (b"", "model/stl"),
        (b"solid nothing\nendsolid\n", "model/stl"),
        (b"<COLLADA", "model/vnd.collada+xml"),
        (b"{}", "model/gltf+json"),
        (b"x", "image/png"),
    ],
)
def test_a_mesh_that_cannot_be_read_is_none(data: bytes, media: str) -> None:
    assert mesh_box(data, media) is None


URDF = """<robot name="r">
  <link name="base"><visual><origin xyz="0 0 0.1" rpy="0 0 1.5707963"/><geometry><box size="0.1 0.2 0.3"/></geometry></visual></link>
  <link name="arm">
    <visual><origin xyz="0 0.1 0"/><geometry><cylinder radius="0.05" length="0.4"/></geometry></visual>
    <visual><geometry><sphere radius="0.07"/></geometry></visual>
    <visual><geometry><mesh filename="missing_mesh.stl"/></geometry></visual>
  </link>
  <joint name="j" type="fixed"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.5"/></joint>
</robot>"""


def test_urdf_primitives_are_boxed_where_rerun_draws_them(tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(URDF)
    chunks = UrdfTree.from_file_path(path, entity_path_prefix="robot").stream(include_joint_transforms=True).to_chunks()
    boxes = geometry_boxes(chunks)
    by_path = dict(zip(boxes.paths, zip(boxes.frames, boxes.corners, strict=True), strict=True))
    frame, corners = by_path["/robot/r/visual_geometries/base/visual_0"]
    assert frame == "base"
    _assert_box((corners.min(axis=0), corners.max(axis=0)), [-0.1, -0.05, -0.05], [0.1, 0.05, 0.25])  # turned 90 degrees about z
    _, cylinder = by_path["/robot/r/visual_geometries/arm/visual_0"]
    _assert_box((cylinder.min(axis=0), cylinder.max(axis=0)), [-0.05, 0.05, -0.2], [0.05, 0.15, 0.2])
    _, sphere = by_path["/robot/r/visual_geometries/arm/visual_1"]
    _assert_box((sphere.min(axis=0), sphere.max(axis=0)), [-0.07] * 3, [0.07] * 3)
    if "/robot/r/visual_geometries/arm/visual_2" in by_path:  # Rerun streams the unresolved mesh without its content
        _, unknown = by_path["/robot/r/visual_geometries/arm/visual_2"]
        assert np.ptp(unknown, axis=0).max() <= 2 * FALLBACK_HALF_SIZE + 1e-9
    transforms = read_transforms(chunks, None)
    arm = boxes.under(["/robot/r/visual_geometries/arm"])
    assert set(arm.frames) == {"arm"}
    world = arm.world(transforms.poses("base", arm.frames, np.zeros(1, np.int64)))
    assert world[:, 2].min() == pytest.approx(0.5 - 0.2) and world[:, 2].max() == pytest.approx(0.5 + 0.2), "placed by the fixed joint"


def test_the_example_pandas_meshes_are_read(examples_dir: Path) -> None:
    """Each COLLADA mesh of the Panda: a box a few centimetres to a few decimetres across, none the fallback."""
    meshes = sorted((examples_dir / "robots/share/example-robot-data/robots/panda_description/meshes/visual").glob("*.dae"))
    assert len(meshes) >= 10
    for mesh in meshes:
        box = mesh_box(mesh.read_bytes(), "model/vnd.collada+xml")
        assert box is not None, mesh.name
        size = box[1] - box[0]
        assert 0.005 < size.max() < 0.4, (mesh.name, size)

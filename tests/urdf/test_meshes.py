"""Mesh URIs resolve as ROS and pinocchio read them, stay inside their package and the config's roots, and hold meshes."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.confine import ALLOW_ENV, confinement_for
from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf.meshes import MeshUriRefused, MeshUriUnread, candidates, mesh_content_problem, resolve_meshes
from urdf_pipeline.urdf.model import MeshRef

MESH_SUFFIXES = (".stl", ".dae", ".obj", ".gltf", ".glb")
COLLADA = b'<?xml version="1.0" encoding="utf-8"?>\n<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1"/>'


def binary_stl(triangles: int) -> bytes:
    return b"\0" * 80 + struct.pack("<I", triangles) + b"\1" * 50 * triangles


@pytest.mark.parametrize(
    ("uri", "expected"),
    [
        ("package://pkg/meshes/a.stl", "PKG/meshes/a.stl"),
        ("package:///pkg/meshes/a.stl", "PKG/meshes/a.stl"),  # talos_data's form: pinocchio reads it as package://pkg/...
        ("model://pkg/meshes/a.stl", "PKG/meshes/a.stl"),  # Gazebo's form, resolved like a package (as pinocchio does)
        ("package://pkg//meshes/a.stl", "PKG/meshes/a.stl"),  # a doubled slash does not make the path absolute
        ("package://pkg/meshes/../a%20b.stl", "PKG/meshes/../a b.stl"),  # inside the package: fine
        ("file:///abs/a.stl", "/abs/a.stl"),
        ("meshes/a.stl", "URDF/meshes/a.stl"),
        ("/abs/a.stl", "/abs/a.stl"),
    ],
)
def test_uri_forms_resolve_like_ros_and_pinocchio(uri: str, expected: str, tmp_path: Path) -> None:
    package, urdf_dir = tmp_path / "pkg_root", tmp_path / "robot"
    found = candidates(uri, {"pkg": package}, urdf_dir)
    assert str(found[0]) == expected.replace("PKG", str(package)).replace("URDF", str(urdf_dir))


@pytest.mark.parametrize(
    "uri", ["package://pkg/../../x.stl", "package://pkg/a/../../../etc/x.stl", "package://pkg/%2e%2e/x.stl", "package://../x.stl"]
)
def test_a_package_path_that_leaves_its_package_is_refused(uri: str, tmp_path: Path) -> None:
    with pytest.raises(MeshUriRefused, match="leaves its package"):
        candidates(uri, {"pkg": tmp_path}, tmp_path)


@pytest.mark.parametrize(
    ("uri", "reason"),
    [
        ("https://example.com/a.stl", "https:// is not read: a run has no network"),
        ("http://example.com/a.stl", "http:// is not read: a run has no network"),
        ("s3://bucket/a.stl", "s3:// is not a form ROS resolves"),
        ("file://host/a.stl", "a host part is not read"),
        ("package:///", "names no package"),
    ],
)
def test_forms_that_are_not_read_name_the_form(uri: str, reason: str, tmp_path: Path) -> None:
    with pytest.raises(MeshUriUnread, match=reason):
        candidates(uri, {}, tmp_path)


def _mesh_files(directory: Path) -> dict[str, bytes]:
    return {
        "binary.stl": binary_stl(3),
        "empty_binary.STL": binary_stl(0),
        "ascii.stl": b"solid cube\n  facet normal 0 0 1\n    outer loop\n",
        "mesh.dae": COLLADA,
        "mesh.DAE": b"\xef\xbb\xbf" + COLLADA,
        "mesh.obj": b"# a comment\nmtllib m.mtl\no cube\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        "mesh.gltf": b'{"buffers": [], "asset": {"version": "2.0"}}',
        "mesh.glb": b"glTF" + struct.pack("<II", 2, 12),
    }


def test_real_formats_pass_the_content_check(tmp_path: Path) -> None:
    for name, content in _mesh_files(tmp_path).items():
        (tmp_path / name).write_bytes(content)
        assert mesh_content_problem(tmp_path / name) is None, name


@pytest.mark.parametrize(
    ("name", "content", "problem"),
    [
        ("random.stl", np.random.default_rng(1).bytes(1000), "is not an STL file"),
        ("empty.stl", b"", "is empty"),
        ("short.stl", b"solid x\n", "is not an STL file"),
        ("count_wrong.stl", binary_stl(3)[:-1], "is not an STL file"),
        ("text.dae", b"hello, not XML at all", "is not a COLLADA file (not XML"),
        ("html.dae", b"<html><body/></html>", "its XML root is <html>, not <COLLADA>"),
        ("bomb.dae", b'<?xml version="1.0"?><!DOCTYPE l [<!ENTITY a "aaaa"><!ENTITY b "&a;&a;">]><COLLADA x="&b;"/>', "DOCTYPE"),
        ("random.dae", np.random.default_rng(2).bytes(1000), "is not a COLLADA file"),
        ("binary.obj", np.random.default_rng(3).bytes(1000) + b"\0", "it is binary"),
        ("text.obj", b"# just a comment\nf 1 2 3\n", "no vertex line"),
        ("list.gltf", b"[1, 2, 3]", "not a JSON object"),
        ("noasset.gltf", b'{"buffers": []}', 'without "asset"'),
        ("random.glb", np.random.default_rng(4).bytes(100), "does not start with the magic `glTF`"),
        ("hostname", b"runner-42\n", "has the suffix '', not one of the mesh formats"),
        ("robot.mesh", b"\0\1\2", "has the suffix '.mesh'"),
    ],
)
def test_garbage_is_refused_naming_why(name: str, content: bytes, problem: str, tmp_path: Path) -> None:
    (tmp_path / name).write_bytes(content)
    found = mesh_content_problem(tmp_path / name)
    assert found is not None and problem in found, found


def _shipped_meshes(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.suffix.lower() in MESH_SUFFIXES and p.is_file()]


def test_every_mesh_of_example_robot_data_passes(erd_share: Path) -> None:
    meshes = _shipped_meshes(erd_share)
    assert len(meshes) > 700  # 777 with example-robot-data 4.x: .stl/.STL, .dae/.DAE, .obj
    assert [(p, mesh_content_problem(p)) for p in meshes if mesh_content_problem(p) is not None] == []


def test_every_mesh_of_rtb_data_passes() -> None:
    rtbdata = pytest.importorskip("rtbdata")
    meshes = _shipped_meshes(Path(rtbdata.__file__).parent)
    assert len(meshes) > 300
    assert [(p, mesh_content_problem(p)) for p in meshes if mesh_content_problem(p) is not None] == []


def test_a_symlinked_mesh_is_read_where_it_points(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A mesh inside the config's folder that links outside it is refused; URDF_PIPELINE_ALLOW_PATHS allows it."""
    outside, config_dir = tmp_path / "outside", tmp_path / "pr"
    outside.mkdir()
    (config_dir / "meshes").mkdir(parents=True)
    (outside / "secret.stl").write_bytes(binary_stl(1))
    (config_dir / "meshes" / "link.stl").symlink_to(outside / "secret.stl")
    meshes = (MeshRef("base", "meshes/link.stl", "visual"),)
    urdf = config_dir / "r.urdf"

    resolution = resolve_meshes(meshes, {}, urdf, confinement_for(config_dir / "c.yaml"), None)
    assert not resolution.resolved
    (error,) = resolution.refused
    assert f"r.urdf, link 'base': visual mesh meshes/link.stl, file {config_dir}/meshes/link.stl" in error.message
    assert f"(resolves to {outside}/secret.stl) is outside the config's folder" in error.message

    monkeypatch.setenv(ALLOW_ENV, str(outside))
    resolution = resolve_meshes(meshes, {}, urdf, confinement_for(config_dir / "c.yaml"), None)
    assert resolution.resolved == {"meshes/link.stl": outside / "secret.stl"} and not resolution.refused


def test_a_mesh_inside_git_is_refused(tmp_path: Path) -> None:
    (tmp_path / ".git").mkdir()
    (tmp_path / ".git" / "config.stl").write_bytes(binary_stl(1))
    resolution = resolve_meshes(
        (MeshRef("base", ".git/config.stl", "visual"),), {}, tmp_path / "r.urdf", confinement_for(tmp_path / "c.yaml"), None
    )
    (error,) = resolution.refused
    assert "is inside a .git folder" in error.message


# End to end: a robot whose one link's visual mesh is `uri` (files written beside the config).

URDF = """<robot name="r">
  <link name="base"><visual><geometry><mesh filename="{uri}"/></geometry></visual></link>
  <link name="arm"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>
"""


def write_mesh_robot(directory: Path, uri: str, **robot: object) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "r.urdf").write_text(URDF.format(uri=uri), encoding="utf-8")
    write_joint_parquet(directory / "d.parquet", np.zeros((3, 1)))
    config = {
        "version": 1,
        "sources": {"s": {"parquet": "d.parquet", "column": "observation.state", "index": "frame_index", "names": ["j"]}},
        "robots": {"arm": {"urdf": "r.urdf", **robot, "joints": {"source": "s", "map": {"j": "j1"}}}},
        "output": {"path": "out/x.rrd", "application_id": "x", "segment": "x"},
    }
    path = directory / "c.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path


def test_package_uri_with_empty_name_runs(tmp_path: Path, run_cli) -> None:
    package = tmp_path / "pr" / "my_pkg"
    (package / "meshes").mkdir(parents=True)
    (package / "meshes" / "base.stl").write_bytes(binary_stl(2))
    config = write_mesh_robot(tmp_path / "pr", "package:///my_pkg/meshes/base.stl", package_paths={"my_pkg": "my_pkg"})
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err


@pytest.mark.parametrize("uri", ["/etc/hostname", "file:///etc/hostname", "file:///no/such/file.stl", "../../../../../../etc/passwd"])
def test_validate_refuses_a_mesh_outside_the_config_folder(uri: str, tmp_path: Path, run_cli) -> None:
    config = write_mesh_robot(tmp_path / "pr", uri)
    result = run_cli("validate", str(config))
    assert result.code == 1, result.err
    assert f"error: {config}:" in result.err and "robots.arm.urdf: r.urdf, link 'base': visual mesh " in result.err
    assert "is outside the config's folder" in result.err and f"{ALLOW_ENV}=/that/folder" in result.err
    for command in ("plan", "diff"):
        args = [command, str(config)] + ([str(config)] if command == "diff" else [])
        assert run_cli(*args).code == 1


def test_validate_refuses_garbage_and_allow_missing_does_not_excuse_it(tmp_path: Path, run_cli) -> None:
    directory = tmp_path / "pr"
    directory.mkdir()
    (directory / "base.obj").write_bytes(b"")
    config = write_mesh_robot(directory, "base.obj", allow_missing_meshes=True)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert f"r.urdf, link 'base': visual mesh {directory}/base.obj is empty; replace it with the real mesh file" in result.err


def test_a_network_mesh_is_unresolved_naming_the_form(tmp_path: Path, run_cli) -> None:
    config = write_mesh_robot(tmp_path / "pr", "https://example.com/base.stl")
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "1 mesh(es) do not resolve: https://example.com/base.stl (visual of link 'base': https:// is not read" in result.err
    allowed = write_mesh_robot(tmp_path / "allowed", "https://example.com/base.stl", allow_missing_meshes=True)
    result = run_cli("validate", str(allowed))
    assert result.code == 0 and "they will be invisible" in result.err


def test_allowed_paths_let_a_mesh_outside_be_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, run_cli) -> None:
    shared = tmp_path / "shared"
    shared.mkdir()
    (shared / "base.stl").write_bytes(binary_stl(2))
    config = write_mesh_robot(tmp_path / "pr", str(shared / "base.stl"))
    assert run_cli("validate", str(config)).code == 1
    monkeypatch.setenv(ALLOW_ENV, os.pathsep.join([str(tmp_path / "elsewhere"), str(shared)]))
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err

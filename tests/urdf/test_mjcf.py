"""MJCF robots (`urdf: {mjcf: FILE}`): a run's recorded poses against MuJoCo's mj_kinematics, and the read rule and
bounds applied to a stranger's model before MuJoCo opens it (the sweep over dm_control is test_mjcf_sweep.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.confine import confinement_for
from urdf_pipeline.errors import UserError, Where, collect_warnings
from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf.mjcf import load_mjcf

from ..edge_helpers import write_config
from ..mjcf_inputs import ARM, ARM_JOINTS, write_mjcf_inputs
from ..rrd_frames import read_frames, rotation_angle

mujoco = pytest.importorskip("mujoco", reason="MJCF robots need mujoco (pip install 'urdf-pipeline[mjcf]')")

TOLERANCE = 1e-5
FRAMES = 20


def _load(path: Path) -> str:
    with collect_warnings():
        return load_mjcf(path, path.name, confinement_for(path), Where(path, 0))


def _body_poses(model: object, qpos: np.ndarray) -> dict[str, np.ndarray]:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    poses = {}
    for body in range(1, model.nbody):  # type: ignore[attr-defined]
        pose = np.eye(4)
        pose[:3, :3] = data.xmat[body].reshape(3, 3)
        pose[:3, 3] = data.xpos[body]
        poses[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)] = pose
    return poses


def test_run_records_mujocos_poses(examples_dir: Path, run_cli) -> None:
    robots = examples_dir / "robots"
    write_mjcf_inputs(robots)
    model = mujoco.MjModel.from_xml_path(str(robots / "mjcf_arm.xml"))
    low, high = model.jnt_range[:, 0], model.jnt_range[:, 1]
    values = np.random.default_rng(26).uniform(low, high, size=(FRAMES, len(ARM_JOINTS))).astype(np.float32)
    write_joint_parquet(examples_dir / "data" / "mjcf_arm.parquet", values)
    data = {
        "version": 1,
        "sources": {
            "s": {"parquet": "data/mjcf_arm.parquet", "column": "observation.state", "index": "frame_index", "names": list(ARM_JOINTS)}
        },
        "robots": {"arm": {"urdf": {"mjcf": "robots/mjcf_arm.xml"}, "joints": {"source": "s", "map": {name: name for name in ARM_JOINTS}}}},
        "output": {"path": "out/{segment}.rrd", "application_id": "mjcf", "segment": "mjcf_arm"},
    }
    config = write_config(examples_dir, "mjcf_arm", data)

    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    assert "geom floor (plane)" in result.err, "what a URDF cannot draw is said"
    assert "Rerun's URDF loader refuses" not in result.err, "the URDF text needs no repair"
    frames = read_frames(Path(result.out.strip()), "frame_index")
    for frame in (0, 7, FRAMES - 1):
        expected = _body_poses(model, values[frame].astype(np.float64))  # qpos is the joints in order: 4 x 1 dof
        for body, pose in expected.items():
            got = frames.world_pose(body, frame, "world")
            assert np.abs(got[:3, 3] - pose[:3, 3]).max() < TOLERANCE, (body, frame)
            assert rotation_angle(got, pose) < TOLERANCE, (body, frame)


def test_an_include_inside_an_include_is_checked(tmp_path: Path) -> None:
    (tmp_path / "outer.xml").write_text('<mujoco><include file="/etc/hostname"/></mujoco>', encoding="utf-8")
    (tmp_path / "robot.xml").write_text(
        ARM.replace('<include file="mjcf_arm_assets.xml"/>', '<include file="outer.xml"/>'), encoding="utf-8"
    )
    with pytest.raises(UserError, match=r"MJCF <include> file '/etc/hostname' in outer.xml:1: /etc/hostname is outside"):
        _load(tmp_path / "robot.xml")


@pytest.mark.parametrize(
    ("element", "message"),
    [
        ('<texture name="t" type="2d" file="/etc/hostname.png"/>', r"MJCF <texture> file '/etc/hostname.png'"),
        ('<hfield name="h" file="../../../../../../../../etc/x.png"/>', r"MJCF <hfield> file '../../"),
        ('<mesh name="m" file="/etc/hostname.stl"/>', r"MJCF <mesh> file '/etc/hostname.stl'"),
        ('<texture name="c" type="skybox" fileup="/etc/up.png"/>', r"MJCF <texture> file '/etc/up.png'"),
    ],
)
def test_asset_files_outside_the_roots_are_refused(tmp_path: Path, element: str, message: str) -> None:
    write_mjcf_inputs(tmp_path)
    (tmp_path / "robot.xml").write_text(ARM.replace("<worldbody>", f"<asset>{element}</asset><worldbody>"), encoding="utf-8")
    with pytest.raises(UserError, match=message):
        _load(tmp_path / "robot.xml")


def test_an_attached_models_files_are_checked(tmp_path: Path) -> None:
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "hand.xml").write_text('<mujoco><compiler meshdir="../../../../../../../../etc"/></mujoco>', encoding="utf-8")
    (tmp_path / "robot.xml").write_text('<mujoco><asset><model name="hand" file="parts/hand.xml"/></asset></mujoco>', encoding="utf-8")
    with pytest.raises(UserError, match=r"MJCF <compiler meshdir> folder in hand.xml:1: /etc is outside"):
        _load(tmp_path / "robot.xml")


def test_every_compiler_folder_is_checked(tmp_path: Path) -> None:
    write_mjcf_inputs(tmp_path)
    text = ARM.replace("<worldbody>", '<compiler meshdir="/etc"/><compiler meshdir="mjcf_meshes"/><worldbody>')
    (tmp_path / "robot.xml").write_text(text, encoding="utf-8")
    with pytest.raises(UserError, match=r"MJCF <compiler meshdir> folder in robot.xml:7: /etc is outside"):
        _load(tmp_path / "robot.xml")


def test_deeply_nested_includes_are_refused(tmp_path: Path) -> None:
    for level in range(100):
        (tmp_path / f"{level}.xml").write_text(f'<mujoco><include file="{level + 1}.xml"/></mujoco>', encoding="utf-8")
    with pytest.raises(UserError, match=r"nests includes \(or <model> files\) more than 64 deep"):
        _load(tmp_path / "0.xml")


def test_deeply_nested_models_are_refused(tmp_path: Path) -> None:
    for level in range(1000):
        model = f'<mujoco><asset><model name="m" file="{level + 1}.xml"/></asset></mujoco>'
        (tmp_path / f"{level}.xml").write_text(model, encoding="utf-8")
    with pytest.raises(UserError, match=r"nests includes \(or <model> files\) more than 64 deep"):
        _load(tmp_path / "0.xml")


def test_an_include_cycle_is_refused(tmp_path: Path) -> None:
    (tmp_path / "robot.xml").write_text('<mujoco><include file="robot.xml"/></mujoco>', encoding="utf-8")
    with pytest.raises(UserError, match=r"includes itself"):
        _load(tmp_path / "robot.xml")


def test_a_model_beyond_the_memory_bound_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("URDF_PIPELINE_MJCF_MEMORY_MB", "200")  # an empty model compiles within it
    assets = '<texture name="t" type="2d" builtin="checker" width="4096" height="4096"/><hfield name="h" nrow="2048" ncol="2048" size="1 1 1 1"/>'
    model = f'<mujoco><asset>{assets}</asset><worldbody><geom type="hfield" hfield="h"/></worldbody></mujoco>'  # the scan's largest
    (tmp_path / "robot.xml").write_text(model, encoding="utf-8")
    with pytest.raises(UserError, match=r"robot.xml with MuJoCo .*more than 200 MB of memory.*URDF_PIPELINE_MJCF_MEMORY_MB"):
        _load(tmp_path / "robot.xml")


def test_a_model_beyond_the_time_bound_is_stopped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("URDF_PIPELINE_MJCF_TIMEOUT", "1")
    monkeypatch.setenv("URDF_PIPELINE_MJCF_MEMORY_MB", "4096")
    body = '<replicate count="4990" offset="0.1 0 0"><body><geom size="0.01"/></body></replicate>'  # within the scan's bounds
    (tmp_path / "robot.xml").write_text(f"<mujoco><worldbody>{body}</worldbody></mujoco>", encoding="utf-8")  # seconds of compiling
    with pytest.raises(UserError, match=r"robot.xml with MuJoCo (did not end within 1 s|used more than 1 s of CPU|.*more than 4096 MB)"):
        _load(tmp_path / "robot.xml")


def test_without_mujoco_the_form_says_how_to_install_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write_mjcf_inputs(tmp_path)
    import importlib.util

    found = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *rest: None if name == "mujoco" else found(name, *rest))
    with pytest.raises(UserError, match=r"need the mujoco package: pip install 'urdf-pipeline\[mjcf\]'"):
        _load(tmp_path / "mjcf_arm.xml")


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return (
        np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
        @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
        @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    )


def test_a_mesh_is_drawn_where_mujoco_puts_it(tmp_path: Path) -> None:
    """MuJoCo recentres a mesh at its centre of mass and turns it to its principal axes; the URDF draws the file's
    vertices at the frame it moved them from: both must give the same points."""
    import xml.etree.ElementTree as ET

    from ..mjcf_inputs import tetrahedron_stl

    write_mjcf_inputs(tmp_path)
    urdf = ET.fromstring(_load(tmp_path / "mjcf_arm.xml"))
    visual = next(v for v in urdf.iterfind("link[@name='base']/visual") if v.find("geometry/mesh") is not None)
    origin, mesh = visual.find("origin"), visual.find("geometry/mesh")
    assert origin is not None and mesh is not None
    assert mesh.get("filename") == "mjcf_meshes/tetra.stl", "relative to the MJCF file"
    rotation = _rpy_matrix(*(float(v) for v in origin.get("rpy", "").split()))
    scale = np.array([float(v) for v in mesh.get("scale", "").split()])
    facets = np.frombuffer(tetrahedron_stl()[84:], dtype=np.dtype([("n", "<3f4"), ("v", "<3f4", (3,)), ("a", "<u2")]))
    corners = np.unique(facets["v"].reshape(-1, 3), axis=0).astype(np.float64) * scale
    ours = corners @ rotation.T + np.array([float(v) for v in origin.get("xyz", "").split()])  # in the body's frame

    model = mujoco.MjModel.from_xml_path(str(tmp_path / "mjcf_arm.xml"))
    geom = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    mesh_id = model.geom_dataid[geom]
    start, count = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, model.geom_quat[geom])
    theirs = model.mesh_vert[start : start + count].astype(np.float64) @ matrix.reshape(3, 3).T + model.geom_pos[geom]
    assert len(theirs) == len(ours) == 4
    distances = np.linalg.norm(theirs[:, None, :] - ours[None, :, :], axis=2).min(axis=1)
    assert distances.max() < 1e-6, "MuJoCo stores the moved vertices in 32-bit floats"


def test_mujocos_log_is_not_written_beside_the_model(tmp_path: Path) -> None:
    write_mjcf_inputs(tmp_path)
    (tmp_path / "robot.xml").write_text(ARM.replace("<compiler ", '<compiler settotalmass="2" '), encoding="utf-8")  # a warning
    _load(tmp_path / "robot.xml")
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()

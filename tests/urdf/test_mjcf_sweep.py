"""The MJCF sweep: every MJCF file dm_control ships (its suite, locomotion walkers, third-party arms, test assets),
turned into URDF text by `urdf: {mjcf: ...}`'s loader and checked against MuJoCo's own mj_kinematics.

Each model is compiled once by the loader (the bounded child process) and once by MuJoCo in this process; at random
hinge and slide values (within their limits) every body's world pose from pinocchio on the URDF text must equal
MuJoCo's `xpos`/`xquat` within 1e-5 m / rad (free and ball joints at their reference pose: a URDF floating joint is
static). A model the loader refuses must be listed in REFUSED with its reason; a listed refusal that now loads fails.

`python benchmarks/mjcf_sweep.py` prints the table model by model.
"""

from __future__ import annotations

import math
import tempfile
import zlib
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.confine import confinement_for
from urdf_pipeline.errors import UserError, Where, collect_warnings
from urdf_pipeline.urdf.mjcf import load_mjcf

mujoco = pytest.importorskip("mujoco", reason="the MJCF sweep needs mujoco (pip install 'urdf-pipeline[mjcf]')")
dm_control = pytest.importorskip("dm_control", reason="the MJCF sweep's models come from dm_control (the test extra)")
pin = pytest.importorskip("pinocchio")

from ..reference_fk import PinocchioRobot  # noqa: E402
from ..rrd_frames import rotation_angle  # noqa: E402

pytestmark = pytest.mark.slow  # every MJCF file of dm_control, each compiled twice (about 25 s)

TOLERANCE = 1e-5  # m and rad
FRAMES = 3
ROOT = Path(dm_control.__file__).parent
MODELS = sorted(str(path.relative_to(ROOT)) for path in ROOT.rglob("*.xml"))

# model -> a fragment of the loader's message: the models it must refuse (MuJoCo refuses all of these itself).
REFUSED = {
    "mjcf/schema.xml": "Unrecognized XML model type",  # dm_control's schema of MJCF, not a model
    "mjcf/test_assets/attribute_test_schema.xml": "Unrecognized XML model type",
    "mjcf/test_assets/included_with_invalid_filenames.xml": "Error opening file",  # a test of a missing mesh
    "mjcf/test_assets/model_with_invalid_filenames.xml": "not found",  # a test of a missing include
    "mjcf/test_assets/test_model.xml": "mass and inertia of moving bodies",
    "mujoco/testing/assets/model_with_assets.xml": "not found",  # its include is given as an in-memory asset by the test
    # dm_control's wheel lacks the fruit fly's .msh meshes (MuJoCo cannot open them either).
    "locomotion/walkers/assets/build_fruitfly/assets/drosophila.xml": "Error opening file 'assets/head_body.msh'",
    "locomotion/walkers/assets/build_fruitfly/floor.xml": "Error opening file",
    "locomotion/walkers/assets/build_fruitfly/fruitfly.xml": "Error opening file 'head_body.msh'",
    "locomotion/walkers/assets/dog_v2/scene.xml": "repeated name 'grid' in texture",  # it includes two files that define it
}


def _random_qpos(model: object, rng: np.random.Generator) -> np.ndarray:
    """qpos with every hinge and slide at a random value within its range (a band when unlimited), the rest at qpos0."""
    qpos = np.array(model.qpos0, dtype=float)  # type: ignore[attr-defined]
    for joint in range(model.njnt):  # type: ignore[attr-defined]
        kind = int(model.jnt_type[joint])  # type: ignore[attr-defined]
        if kind not in (2, 3):
            continue
        low, high = model.jnt_range[joint] if model.jnt_limited[joint] else ((-math.pi, math.pi) if kind == 3 else (-0.5, 0.5))  # type: ignore[attr-defined]
        qpos[model.jnt_qposadr[joint]] = rng.uniform(low, high)  # type: ignore[attr-defined]
    return qpos


def _mujoco_poses(model: object, qpos: np.ndarray) -> list[np.ndarray]:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    poses = []
    for body in range(model.nbody):  # type: ignore[attr-defined]
        pose = np.eye(4)
        pose[:3, :3] = data.xmat[body].reshape(3, 3)
        pose[:3, 3] = data.xpos[body]
        poses.append(pose)
    return poses


def _joint_values(model: object, qpos: np.ndarray) -> dict[str, float]:
    values = {}
    for joint in range(model.njnt):  # type: ignore[attr-defined]
        if int(model.jnt_type[joint]) in (2, 3):  # type: ignore[attr-defined]
            body = int(model.jnt_bodyid[joint])  # type: ignore[attr-defined]
            first = int(model.body_jntadr[body])  # type: ignore[attr-defined]
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, joint) or f"{_body_name(model, body)}_joint{joint - first}"
            values[name] = float(qpos[model.jnt_qposadr[joint]])  # type: ignore[attr-defined]
    return values


def _body_name(model: object, body: int) -> str:
    return "world" if body == 0 else mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"


def worst_error(relative: str) -> float:
    """The largest position or rotation difference over every body and FRAMES random joint vectors."""
    path = ROOT / relative
    with collect_warnings():
        text = load_mjcf(path, path.name, confinement_for(path), Where(path, 0))
    model = mujoco.MjModel.from_xml_path(str(path))
    with tempfile.TemporaryDirectory() as folder:
        urdf = Path(folder) / "robot.urdf"
        urdf.write_text(text, encoding="utf-8")
        robot = PinocchioRobot(urdf)
    rng = np.random.default_rng(zlib.crc32(relative.encode()))
    worst = 0.0
    for _ in range(FRAMES):
        qpos = _random_qpos(model, rng)
        reference = _mujoco_poses(model, qpos)
        ours = robot.link_poses(_joint_values(model, qpos))
        for body, expected in enumerate(reference):
            got = ours[_body_name(model, body)]
            worst = max(worst, float(np.abs(got[:3, 3] - expected[:3, 3]).max()), rotation_angle(got[:3, :3], expected[:3, :3]))
    return worst


@pytest.mark.parametrize("relative", MODELS)
def test_mjcf_model_matches_mujoco(relative: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warnings to MUJOCO_LOG.TXT in the working folder
    if relative in REFUSED:
        path = ROOT / relative
        with pytest.raises(UserError, match=REFUSED[relative]), collect_warnings():
            load_mjcf(path, path.name, confinement_for(path), Where(path, 0))
        return
    assert worst_error(relative) <= TOLERANCE

"""URDF text from a compiled MuJoCo model (run in mjcf_sandbox's child process): same bodies, same poses.

MuJoCo moves a body by its joints in order, each about its anchor (`jnt_pos`, in the body frame): a hinge rotates the
frame about the anchor, a slide translates it. A URDF joint rotates about its child's origin, so each joint gets a link
of its own at its anchor (`BODY__JOINT`), and a fixed joint takes the frame back from the last anchor to the body's
origin. With no joint a body hangs by a fixed joint. A free joint becomes a floating joint at the body's pose (static,
as the URDF form's floating joints are, and drivable by a temporal edge); a ball joint likewise, at its anchor. Geoms
become visuals (groups 0-2, those MuJoCo's viewer shows) or collisions (group 3 and up); a mesh is drawn from its file
with the frame MuJoCo moved it from (it recentres meshes at compile time: `mesh_pos`, `mesh_quat`).

A hinge or slide with `ref` (MuJoCo moves it by value - ref) takes the -ref turn in its origin, so data holds MuJoCo's
qpos. What a URDF cannot say is refused by name: a free joint below another body, flex objects. Planes, height fields, ellipsoids and meshes without a file are left undrawn (notes).
"""

from __future__ import annotations

import math
import os
import re
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from .geometry import quaternion_multiply

FREE, BALL, SLIDE, HINGE = 0, 1, 2, 3
_PLANE, _HFIELD, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = range(8)
_DRAWN_MESH = (".stl", ".obj", ".dae", ".glb", ".gltf")
_ORIGIN = re.compile(r'<origin xyz="([^"]*)" rpy="([^"]*)"/>')
UNLIMITED_SLIDE = 1e6  # metres: an unlimited slide joint's URDF limits
VISUAL_GROUPS = 3  # MuJoCo's viewer shows geom groups 0, 1 and 2 by default


class NotRepresentable(Exception):
    """A part of the model a URDF cannot hold faithfully; the message names it."""


def _num(value: float) -> str:
    return repr(float(value)) if value != 0 else "0"


def _rpy(quat_wxyz: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a MuJoCo quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in quat_wxyz / np.linalg.norm(quat_wxyz))
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if abs(r[2, 0]) < 1 - 1e-12:
        return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])
    return math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0  # gimbal lock: yaw folded into roll


def _origin(pos: np.ndarray, quat: np.ndarray | None = None) -> str:
    rpy = _rpy(quat) if quat is not None else (0.0, 0.0, 0.0)
    return f'<origin xyz="{" ".join(map(_num, pos))}" rpy="{" ".join(map(_num, rpy))}"/>'


def _quat_from_rpy(rpy: np.ndarray) -> np.ndarray:
    """MuJoCo quaternion (w, x, y, z) of URDF roll, pitch, yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    half = rpy / 2
    rx = np.array([math.cos(half[0]), math.sin(half[0]), 0.0, 0.0])
    ry = np.array([math.cos(half[1]), 0.0, math.sin(half[1]), 0.0])
    rz = np.array([math.cos(half[2]), 0.0, 0.0, math.sin(half[2])])
    return _quat_mul(_quat_mul(rz, ry), rx)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product of MuJoCo's (w, x, y, z) quaternions."""
    x, y, z, w = quaternion_multiply((a[1], a[2], a[3], a[0]), (b[1], b[2], b[3], b[0]))
    return np.array([w, x, y, z])


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    return np.asarray(_quat_mul(_quat_mul(q, np.array([0.0, *v])), conj)[1:])


class _Writer:
    def __init__(self, model: Any, mujoco: Any, folder: str) -> None:
        self.folder = folder  # the MJCF file's: mesh paths are written relative to it, so the text is the same anywhere
        self.m = model
        self.mj = mujoco
        self.lines: list[str] = []
        self.notes: list[str] = []
        self.names: set[tuple[str, str]] = set()

    def name(self, kind: Any, index: int, fallback: str) -> str:
        return self.mj.mj_id2name(self.m, kind, index) or fallback

    def body_name(self, body: int) -> str:
        return "world" if body == 0 else self.name(self.mj.mjtObj.mjOBJ_BODY, body, f"body{body}")

    def unique(self, name: str, what: str) -> str:
        if (what, name) in self.names:
            raise NotRepresentable(f"two URDF {what}s would be named {name!r} (a MuJoCo name and one made for a joint's frame)")
        self.names.add((what, name))
        return name

    def link(self, name: str, body: int | None) -> None:
        self.lines.append(f"  <link name={quoteattr(self.unique(name, 'link'))}>")
        if body is not None:
            for geom in np.flatnonzero(self.m.geom_bodyid == body):
                self.geom(int(geom))
        self.lines.append("  </link>")

    def joint(self, name: str, kind: str, parent: str, child: str, origin: str, extra: str = "") -> None:
        self.lines.append(f"  <joint name={quoteattr(self.unique(name, 'joint'))} type={quoteattr(kind)}>")
        self.lines.append(f"    <parent link={quoteattr(parent)}/><child link={quoteattr(child)}/>{origin}{extra}")
        self.lines.append("  </joint>")

    def geom(self, geom: int) -> None:
        shape = self.shape(geom)
        if shape is None:
            return
        element, pos, quat = shape
        tag = "visual" if self.m.geom_group[geom] < VISUAL_GROUPS else "collision"
        rgba = self.m.geom_rgba[geom]
        color = f'<color rgba="{" ".join(map(_num, rgba))}"/>'
        material = f'<material name="mjcf_geom{geom}">{color}</material>' if tag == "visual" else ""  # Rerun needs a name
        self.lines.append(f"    <{tag}>{_origin(pos, quat)}<geometry>{element}</geometry>{material}</{tag}>")

    def shape(self, geom: int) -> tuple[str, np.ndarray, np.ndarray] | None:
        kind, size = int(self.m.geom_type[geom]), self.m.geom_size[geom]
        pos, quat = self.m.geom_pos[geom], self.m.geom_quat[geom]
        simple = {
            _SPHERE: f'<sphere radius="{_num(size[0])}"/>',
            _CAPSULE: f'<capsule radius="{_num(size[0])}" length="{_num(2 * size[1])}"/>',
            _CYLINDER: f'<cylinder radius="{_num(size[0])}" length="{_num(2 * size[1])}"/>',
            _BOX: f'<box size="{" ".join(_num(2 * s) for s in size)}"/>',
        }
        if kind in simple:
            return simple[kind], pos, quat
        if kind == _MESH:
            return self.mesh(geom, pos, quat)
        what = {_PLANE: "plane", _HFIELD: "height field", _ELLIPSOID: "ellipsoid"}.get(kind, f"type {kind}")
        self.notes.append(f"geom {self.name(self.mj.mjtObj.mjOBJ_GEOM, geom, f'#{geom}')} ({what})")
        return None

    def mesh(self, geom: int, pos: np.ndarray, quat: np.ndarray) -> tuple[str, np.ndarray, np.ndarray] | None:
        mesh = int(self.m.geom_dataid[geom])
        start = int(self.m.mesh_pathadr[mesh])
        path = self.m.paths[start:].split(b"\0", 1)[0].decode("utf-8", "replace") if start >= 0 else ""
        if not path.lower().endswith(_DRAWN_MESH):
            self.notes.append(f"mesh {self.name(self.mj.mjtObj.mjOBJ_MESH, mesh, f'#{mesh}')} ({path or 'no file'})")
            return None
        # The file's frame: the compiled geom frame moved back by the offset MuJoCo applied to the vertices.
        inverse = self.m.mesh_quat[mesh] * np.array([1.0, -1.0, -1.0, -1.0])
        file_quat = _quat_mul(quat, inverse)
        file_pos = pos - _rotate(file_quat, self.m.mesh_pos[mesh])
        scale = " ".join(map(_num, self.m.mesh_scale[mesh]))
        path = os.path.relpath(path, self.folder).replace(os.sep, "/") if os.path.isabs(path) else path
        return f"<mesh filename={quoteattr(path)} scale={quoteattr(scale)}/>", file_pos, file_quat

    def body(self, body: int) -> None:
        """The body's link, with the joints (and their anchor links) that hang it from its parent."""
        name = self.body_name(body)
        parent = self.body_name(int(self.m.body_parentid[body]))
        pos, quat = self.m.body_pos[body], self.m.body_quat[body]
        first, count = int(self.m.body_jntadr[body]), int(self.m.body_jntnum[body])
        if count == 0:  # a mocap body: floating, so a temporal edge can drive it as MuJoCo's mocap_pos does
            hanging = "floating" if self.m.body_mocapid[body] >= 0 else "fixed"
            self.joint(f"{name}__{hanging}", hanging, parent, name, _origin(pos, quat))
            self.link(name, body)
            return
        origin = _origin(pos, quat)
        anchor = np.zeros(3)
        for joint in range(first, first + count):
            kind = int(self.m.jnt_type[joint])
            joint_name = self.name(self.mj.mjtObj.mjOBJ_JOINT, joint, f"{name}_joint{joint - first}")
            if kind == FREE and parent != "world":
                raise NotRepresentable(
                    f"free joint {joint_name!r} is in a body below {parent!r}: a URDF floating joint hangs from its parent, MuJoCo's free joint from the world"
                )
            new_anchor = self.m.jnt_pos[joint] if kind in (HINGE, BALL) else np.zeros(3)
            step = _origin(new_anchor - anchor)
            if joint == first:
                step = origin if not new_anchor.any() else _origin(pos + _rotate(quat, new_anchor), quat)
            step = self.with_ref(joint, kind, step)
            frame = f"{name}__{joint_name}"
            urdf_type = {FREE: "floating", BALL: "floating", SLIDE: "prismatic"}.get(kind) or (
                "revolute" if self.m.jnt_limited[joint] else "continuous"
            )
            self.joint(joint_name, urdf_type, parent, frame, step, self.limits(joint, kind))
            self.link(frame, None)
            parent, anchor = frame, new_anchor
        self.joint(f"{name}__anchor", "fixed", parent, name, _origin(-anchor))
        self.link(name, body)

    def with_ref(self, joint: int, kind: int, step: str) -> str:
        """A hinge or slide with `ref` moves by (value - ref): the joint's origin takes the -ref turn or shift (about or
        along its own axis, so it commutes with the joint), and the value stays MuJoCo's qpos."""
        ref = float(self.m.qpos0[int(self.m.jnt_qposadr[joint])])
        if kind not in (HINGE, SLIDE) or ref == 0:
            return step
        xyz, rpy = (np.array([float(v) for v in part.split(" ")]) for part in _ORIGIN.fullmatch(step).groups())  # type: ignore[union-attr]
        frame = _quat_from_rpy(rpy)
        axis = self.m.jnt_axis[joint]
        if kind == SLIDE:
            return _origin(xyz + _rotate(frame, -ref * axis), frame)
        turn = np.array([math.cos(-ref / 2), *(math.sin(-ref / 2) * axis)])
        return _origin(xyz, _quat_mul(frame, turn))

    def limits(self, joint: int, kind: int) -> str:
        if kind not in (HINGE, SLIDE):
            return ""
        axis = f'<axis xyz="{" ".join(map(_num, self.m.jnt_axis[joint]))}"/>'
        if not self.m.jnt_limited[joint]:
            if kind == HINGE:
                return axis  # a continuous joint
            lower, upper = -UNLIMITED_SLIDE, UNLIMITED_SLIDE  # URDF readers (urdfdom) require a prismatic joint's limits
        else:
            lower, upper = self.m.jnt_range[joint]
        return f'{axis}<limit lower="{_num(lower)}" upper="{_num(upper)}" effort="0" velocity="0"/>'


def urdf_from_model(model: Any, mujoco: Any, robot_name: str, folder: str) -> tuple[str, list[str]]:
    """The URDF text of `model` (compiled from a file in `folder`) and the geoms left undrawn; NotRepresentable for what a
    URDF cannot hold."""
    if model.nflex:
        raise NotRepresentable(f"the model has {model.nflex} flex object(s) (deformable bodies): a URDF has rigid links only")
    writer = _Writer(model, mujoco, folder)
    writer.lines.append(f"<robot name={quoteattr(robot_name)}>")
    writer.link("world", 0)
    for body in range(1, model.nbody):
        writer.body(body)
    writer.lines.append("</robot>")
    return "\n".join(writer.lines) + "\n", writer.notes

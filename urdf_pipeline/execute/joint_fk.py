"""Joint transforms in closed form, over whole columns: what Rerun's `UrdfTree.compute_joint_transform_batches`
returns, 4-7x faster (FK was over half the CPU time of a run).

A revolute or continuous joint turns by q about its axis (quaternion = origin ⊗ (axis·sin(q/2), cos(q/2))), a
prismatic joint slides by q along it (translation = origin xyz + R(origin)·axis·q). Rerun stays the reference: the
frames come from Rerun's own parse of the URDF, and every instance is checked against Rerun's FK on probe values at
construction; a joint kind or convention this code does not know (off by more than `AGREEMENT`) uses Rerun's FK.

`compose` is the one composition of transforms down a tree of frames, in float64 over whole columns.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

import numpy as np
import pyarrow as pa

from .transform_lenses import float_vectors, transform_lists

if TYPE_CHECKING:
    from rerun.urdf import UrdfTree

Frame = TypeVar("Frame", bound=Hashable)
Pose = tuple[np.ndarray, np.ndarray]  # rows x 3 translations (metres), rows x 4 (x, y, z, w) quaternions; float64

AGREEMENT = 1e-5  # m and quaternion components: Rerun computes in float32 (~1e-7), a wrong formula is off by far more
PROBES = np.array([0.0, 0.37, -1.21, 2.53, -3.07, 0.0031])  # every joint at each value, and one row of mixed values
_MOVING = ("revolute", "continuous", "prismatic")


def probe_values(count: int) -> np.ndarray:
    """`count` joints at each of `PROBES`, and one row of mixed values: what a fast path is checked on."""
    mixed = np.resize(PROBES[1:], count)
    return np.vstack([np.repeat(PROBES[:, None], count, axis=1), mixed[None, :]])


class ClosedFormJointTransforms:
    """Joint values (rows × joints, the order of `names`) -> Rerun's list<struct> joint-transform batches."""

    def __init__(self, tree: UrdfTree, names: list[str]) -> None:
        self.tree = tree
        self.names = names
        found = [tree.get_joint_by_name(name) for name in names]
        joints = [joint for joint in found if joint is not None and joint.joint_type in _MOVING]
        self.usable = len(joints) == len(names)
        if not self.usable:
            return
        origin_q = np.array([quaternion_from_rpy(*joint.origin_rpy) for joint in joints], dtype=np.float64)
        axes = np.array([joint.axis for joint in joints], dtype=np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):  # a zero axis: NaN, then the check below leaves it to Rerun
            axes /= np.linalg.norm(axes, axis=1, keepdims=True)  # unit already (urdf.repair normalises): kept exact
        prismatic = np.array([joint.joint_type == "prismatic" for joint in joints])
        self.half_turning = 0.5 * (~prismatic).astype(np.float64)
        self.sliding = prismatic.astype(np.float64)
        self.origin_q = origin_q
        self.origin_q32 = origin_q.astype(np.float32)
        self.origin_t = np.array([joint.origin_xyz for joint in joints], dtype=np.float64)
        self.axis_q = multiply_quaternions(origin_q, np.concatenate([axes, np.zeros((len(names), 1))], axis=1))
        self.axis_q32 = self.axis_q.astype(np.float32)
        self.slide_axes = rotate(origin_q, axes)
        reference = self._rerun(np.zeros((1, len(names))))
        self._sizes: dict[int, _SizeConstants] = {}
        self._lock = threading.Lock()
        frames = reference.values
        self.parents = _Repeated(frames.field("parent_frame").to_pylist())
        self.children = _Repeated(frames.field("child_frame").to_pylist())
        self.usable = self._agrees_with_rerun()

    def __call__(self, values: np.ndarray) -> pa.Array:
        """`values`: float64, rows × joints. Rerun's FK when this robot did not pass the check at construction.
        Infinite values are refused after the pass (they give NaN here): numpy's warnings about them say nothing."""
        if not self.usable:
            return self._rerun(values)
        with np.errstate(invalid="ignore", over="ignore"):
            return self._closed_form(values)

    def _closed_form(self, values: np.ndarray) -> pa.Array:
        rows, count = values.shape
        fixed = self._per_size(rows)
        half = values * self.half_turning  # float64 up to the sines: a wheel at 1000 rad keeps its 1e-5
        sines, cosines = np.sin(half).astype(np.float32), np.cos(half).astype(np.float32)
        quaternion = np.empty((rows, count, 4), dtype=np.float32)
        np.multiply(sines[..., None], self.axis_q32, out=quaternion)
        quaternion += cosines[..., None] * self.origin_q32
        translation = fixed.translation
        if translation is None:
            translation = float_vectors(self.origin_t + (values * self.sliding)[..., None] * self.slide_axes)
        return transform_lists(fixed.offsets, translation, float_vectors(quaternion), fixed.parents, fixed.children)

    def arrays(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The same transforms as numpy arrays in float64 (rows x joints x 3 translations, x 4 quaternions), for
        analysis (`kinematics.py`): not rounded to float32 as the recording's are."""
        rows, count = values.shape
        if not self.usable:
            batches = self._rerun(values).values
            translation = np.asarray(batches.field("translation").flatten(), dtype=np.float64).reshape(rows, count, 3)
            return translation, np.asarray(batches.field("quaternion").flatten(), dtype=np.float64).reshape(rows, count, 4)
        with np.errstate(invalid="ignore", over="ignore"):
            half = values * self.half_turning
            quaternion = np.sin(half)[..., None] * self.axis_q + np.cos(half)[..., None] * self.origin_q
            translation = self.origin_t + (values * self.sliding)[..., None] * self.slide_axes
        return translation, quaternion

    def link_poses(self, values: np.ndarray, root: str | None = None, at: Pose | None = None) -> dict[str, Pose]:
        """Every link below `root` (default: the tree's root link) placed in its frame at each row of `values`, in
        float64 (`at`: root's own pose, to place them in a frame above it): the joints of `names` by `arrays`, every
        other joint (fixed, floating, planar) at its URDF origin, as Rerun's model logs it."""
        local_t, local_q = self.arrays(values)
        moving = {name: index for index, name in enumerate(self.names)}
        above = {joint.child_link: joint for joint in self.tree.joints()}

        def local(link: str) -> Pose:
            joint = above[link]
            if joint.name in moving:
                return local_t[:, moving[joint.name]], local_q[:, moving[joint.name]]
            return np.array(joint.origin_xyz, dtype=np.float64), np.array(quaternion_from_rpy(*joint.origin_rpy), dtype=np.float64)

        top = self.tree.root_link().name if root is None else root
        return compose(top, [(joint.parent_link, joint.child_link) for joint in self.tree.joints()], local, len(values), at)

    def _per_size(self, rows: int) -> _SizeConstants:
        """What depends only on the row count (frames, offsets, the translations of a robot without prismatic
        joints): blocks mostly share one size, so these are made a few times per run, not per block."""
        with self._lock:  # lens callbacks may run on several of Rerun's threads
            fixed = self._sizes.get(rows)
            if fixed is None:
                fixed = self._sizes[rows] = self._size_constants(rows)
                if len(self._sizes) > 4:
                    self._sizes.pop(next(iter(self._sizes)))
        return fixed

    def _size_constants(self, rows: int) -> _SizeConstants:
        translation = None
        if not self.sliding.any():
            translation = float_vectors(np.tile(self.origin_t.astype(np.float32), (rows, 1)))
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * len(self.names))
        return _SizeConstants(offsets, self.parents.rows(rows), self.children.rows(rows), translation)

    def _rerun(self, values: np.ndarray) -> pa.Array:
        rows, count = values.shape
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * count)
        names = pa.ListArray.from_arrays(offsets, _Repeated(self.names).rows(rows))
        # Fresh float64 arrays per call: zero-copy slices of one big array make Rerun's FK quadratic.
        value_lists = pa.ListArray.from_arrays(offsets, pa.array(np.ascontiguousarray(values, dtype=np.float64).reshape(-1)))
        return self.tree.compute_joint_transform_batches(names, value_lists)

    def _agrees_with_rerun(self) -> bool:
        probes = probe_values(len(self.names))
        ours, theirs = self(probes).values, self._rerun(probes).values
        if not (
            ours.field("parent_frame").equals(theirs.field("parent_frame"))
            and ours.field("child_frame").equals(theirs.field("child_frame"))
        ):
            return False
        t_ours, t_theirs = (np.asarray(v.field("translation").flatten()).reshape(-1, 3) for v in (ours, theirs))
        q_ours, q_theirs = (np.asarray(v.field("quaternion").flatten()).reshape(-1, 4) for v in (ours, theirs))
        same_sign = np.abs(q_ours - q_theirs).max(axis=1)
        either_sign = np.minimum(same_sign, np.abs(q_ours + q_theirs).max(axis=1))  # q and -q: the same rotation
        return bool(np.abs(t_ours - t_theirs).max() <= AGREEMENT and either_sign.max() <= AGREEMENT)


@dataclass(frozen=True)
class _SizeConstants:
    offsets: pa.Array
    parents: pa.Array
    children: pa.Array
    translation: pa.Array | None  # None: a prismatic joint moves it


class _Repeated:
    """One string per joint, repeated for every row: built from the bytes with numpy, not string by string."""

    def __init__(self, strings: list[str]) -> None:
        encoded = [s.encode() for s in strings]
        self.lengths = np.array([len(b) for b in encoded], dtype=np.int64)
        self.data = np.frombuffer(b"".join(encoded), dtype=np.uint8)

    def rows(self, rows: int) -> pa.Array:
        total = int(self.lengths.sum()) * rows
        offsets = np.zeros(rows * len(self.lengths) + 1, dtype=np.int32 if total < 2**31 else np.int64)
        np.cumsum(np.tile(self.lengths, rows), out=offsets[1:])
        kind = pa.string() if offsets.dtype == np.int32 else pa.large_string()
        array = pa.Array.from_buffers(kind, rows * len(self.lengths), [None, pa.py_buffer(offsets), pa.py_buffer(np.tile(self.data, rows))])
        return array if kind == pa.string() else array.cast(pa.string())  # past 2 GiB the cast raises, as Rerun's FK would fail


def compose(
    root: Frame, edges: Iterable[tuple[Frame, Frame]], local: Callable[[Frame], Pose], rows: int, at: Pose | None = None
) -> dict[Frame, Pose]:
    """Every frame below `root` placed in root's frame (or, given root's pose `at`, in the frame above it) at each of
    `rows` rows: each child's `local` transform (parent from child; one pose is broadcast to every row) composed from
    the root down, one step per frame over all rows. `edges` are (parent, child); a frame reached twice keeps its
    first placement (the frame graph check refuses that before anything is written)."""
    children: dict[Frame, list[Frame]] = {}
    for parent, child in edges:
        children.setdefault(parent, []).append(child)
    start_t, start_q = at or (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    placed = {root: (np.broadcast_to(start_t, (rows, 3)), np.broadcast_to(start_q, (rows, 4)))}
    stack = [root]
    while stack:
        parent = stack.pop()
        parent_t, parent_q = placed[parent]
        for child in children.get(parent, ()):
            if child in placed:
                continue
            t, q = local(child)
            placed[child] = (
                parent_t + rotate(parent_q, np.broadcast_to(t, (rows, 3))),
                multiply_quaternions(parent_q, np.broadcast_to(q, (rows, 4))),
            )
            stack.append(child)
    return placed


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> list[float]:
    """URDF's fixed-axis roll, pitch, yaw (R = Rz·Ry·Rx) as (x, y, z, w)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2), np.cos(yaw / 2), np.sin(yaw / 2)
    return [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy]


def multiply_quaternions(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products of (x, y, z, w) quaternions, row by row."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=1,
    )


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Each vector of `v` rotated by the unit quaternion of its row of `q`."""
    u, w = q[:, :3], q[:, 3:]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def rotation_matrices(quaternions: np.ndarray) -> np.ndarray:
    """(..., 4) (x, y, z, w) quaternions, normalised here, as (..., 3, 3) rotation matrices."""
    q = quaternions / np.linalg.norm(quaternions, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )

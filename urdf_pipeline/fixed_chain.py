"""fixed_chain edges: the pose of one URDF link in another, composed across the URDF's fixed joints only.

`{parent: gripper_link, child: wrist_cam, fixed_chain: {from: gripper_link, to: camera_mount}}` logs the pose of
`camera_mount` in `gripper_link` as the static edge gripper_link -> wrist_cam. The walk goes down from `from`
through fixed joints only; a moving joint on the way means the pose changes over time and is refused.
"""

from __future__ import annotations

import math

from .geometry import quaternion_from_rpy
from .urdf_model import Joint, UrdfModel

Vector = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]  # x, y, z, w


class NoFixedChain(Exception):
    """The walk through fixed joints from `start` cannot reach `end`.

    `stuck` is the deepest ancestor of `end` that the walk reaches (or `start` when `end` is not below it at all);
    `blocking` is the joint just below `stuck` on the way to `end` (a moving joint), None when `end` is not below;
    `end_is_above` says `end` is an ancestor of `start` (from and to are probably swapped).
    """

    def __init__(self, stuck: str, blocking: Joint | None, end_is_above: bool) -> None:
        super().__init__(stuck)
        self.stuck = stuck
        self.blocking = blocking
        self.end_is_above = end_is_above


def find_fixed_chain(model: UrdfModel, start: str, end: str) -> tuple[Joint, ...]:
    """The fixed joints from link `start` down to link `end` (unprefixed names), top down; raise NoFixedChain."""
    children: dict[str, list[Joint]] = {}
    for joint in model.joints:
        children.setdefault(joint.parent, []).append(joint)
    reached: dict[str, tuple[Joint, ...]] = {start: ()}
    frontier = [start]
    while frontier:
        link = frontier.pop()
        for joint in children.get(link, ()):
            if joint.type == "fixed" and joint.child not in reached:
                reached[joint.child] = (*reached[link], joint)
                frontier.append(joint.child)
    if end in reached:
        return reached[end]
    parent_joint = {joint.child: joint for joint in model.joints}
    link = end
    while link in parent_joint:
        joint = parent_joint[link]
        if joint.parent in reached:
            raise NoFixedChain(joint.parent, joint, end_is_above=False)
        link = joint.parent
    raise NoFixedChain(start, None, end_is_above=_is_ancestor(end, start, parent_joint))


def _is_ancestor(candidate: str, link: str, parent_joint: dict[str, Joint]) -> bool:
    seen: set[str] = set()
    while link in parent_joint and link not in seen:
        seen.add(link)
        link = parent_joint[link].parent
        if link == candidate:
            return True
    return False


def quaternion_multiply(a: Quaternion, b: Quaternion) -> Quaternion:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def rotate(q: Quaternion, v: Vector) -> Vector:
    """v rotated by the unit quaternion q (q v q*)."""
    x, y, z, w = q
    # t = 2 (q_vec x v); v' = v + w t + q_vec x t
    tx = 2 * (y * v[2] - z * v[1])
    ty = 2 * (z * v[0] - x * v[2])
    tz = 2 * (x * v[1] - y * v[0])
    return (
        v[0] + w * tx + (y * tz - z * ty),
        v[1] + w * ty + (z * tx - x * tz),
        v[2] + w * tz + (x * ty - y * tx),
    )


def compose_chain(joints: tuple[Joint, ...]) -> tuple[Vector, Quaternion]:
    """Pose of the last joint's child in the first joint's parent: each joint's origin (xyz, URDF rpy) in turn."""
    translation: Vector = (0.0, 0.0, 0.0)
    rotation: Quaternion = (0.0, 0.0, 0.0, 1.0)
    for joint in joints:
        step = rotate(rotation, joint.xyz)
        translation = (translation[0] + step[0], translation[1] + step[1], translation[2] + step[2])
        rotation = quaternion_multiply(rotation, quaternion_from_rpy(*joint.rpy))
    norm = math.sqrt(sum(v * v for v in rotation))
    x, y, z, w = (v / norm for v in rotation)
    return translation, (x, y, z, w)

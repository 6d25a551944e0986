"""fixed_chain edges: the pose of one URDF link in another, composed across the URDF's fixed joints only.

`{parent: gripper_link, child: wrist_cam, fixed_chain: {from: gripper_link, to: camera_mount}}` logs the pose of
`camera_mount` in `gripper_link` as the static edge gripper_link -> wrist_cam. The walk goes down from `from`
through fixed joints only; a moving joint on the way means the pose changes over time and is refused.
"""

from __future__ import annotations

from .geometry import Quaternion, Vector, normalized_quaternion, quaternion_from_rpy, quaternion_multiply, rotate
from .model import Joint, UrdfModel


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
    reached: dict[str, Joint | None] = {start: None}  # each link the walk reaches, and the joint it came through
    frontier = [start]
    while frontier:
        link = frontier.pop()
        for joint in children.get(link, ()):
            if joint.type == "fixed" and joint.child not in reached:
                reached[joint.child] = joint
                frontier.append(joint.child)
    if end in reached:
        chain: list[Joint] = []
        step = reached[end]
        while step is not None:  # back up from `end`: linear in the chain, however long
            chain.append(step)
            step = reached[step.parent]
        return tuple(reversed(chain))
    parent_joint = {joint.child: joint for joint in model.joints}
    link = end
    while link in parent_joint:
        joint = parent_joint[link]
        if joint.parent in reached:
            raise NoFixedChain(joint.parent, joint, end_is_above=False)
        link = joint.parent
    raise NoFixedChain(start, None, end_is_above=start in model.below(end))


def compose_chain(joints: tuple[Joint, ...]) -> tuple[Vector, Quaternion]:
    """Pose of the last joint's child in the first joint's parent: each joint's origin (xyz, URDF rpy) in turn."""
    translation: Vector = (0.0, 0.0, 0.0)
    rotation: Quaternion = (0.0, 0.0, 0.0, 1.0)
    for joint in joints:
        step = rotate(rotation, joint.xyz)
        translation = (translation[0] + step[0], translation[1] + step[1], translation[2] + step[2])
        rotation = quaternion_multiply(rotation, quaternion_from_rpy(*joint.rpy))
    unit = normalized_quaternion(rotation)
    assert unit is not None  # a product of unit quaternions is never zero
    return translation, unit

"""Trails (`trails:`): a link's position in a chosen frame at every row, from the FK pass's own joint values.

For each trail the FK's compute lens moves the link's origin up through the URDF joints and the static calibration
edges to the trail's frame, over the whole block in float64 (checked at construction against `link_poses`, used
instead should they differ), and returns the positions beside the transforms; a second lens writes them to the
trail's entity: `points` one position per row, `line` one segment from the previous row's position. Nothing is kept
beyond a block and one position per trail; the blueprint's visible time range (blueprint.py) shows the window.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from ..plan import TrailPlan
from .joint_fk import ClosedFormJointTransforms, Pose, compose, probe_values, quaternion_from_rpy, rotation_matrices
from .transform_lenses import float_type, float_vectors

if TYPE_CHECKING:
    import rerun.blueprint as rrb
    from rerun.chunk import DeriveLens, LazyChunkStream
    from rerun.urdf import UrdfJoint, UrdfTree

STRIP_TYPE = pa.list_(pa.field("item", float_type(3), nullable=False))  # LineStrip3D's
TRAIL_RADIUS = 0.004  # m: points and lines thin enough not to hide the link they follow


def trail_field(index: int) -> str:
    return f"trail_{index}"


class TrailPositions:
    """One trail's positions for a block of URDF values (the FK's matrix, columns in `names`' order)."""

    def __init__(self, trail: TrailPlan, tree: UrdfTree, names: list[str]) -> None:
        self.trail = trail
        edges = {edge.child: edge for edge in trail.edges}  # the static edges from the frame down to the robot's root link

        def edge_pose(child: str) -> Pose:
            edge = edges[child]
            return np.array(edge.translation), np.array(edge.quaternion_xyzw, dtype=np.float64) / np.linalg.norm(edge.quaternion_xyzw)

        placed = compose(trail.frame, [(edge.parent, edge.child) for edge in trail.edges], edge_pose, 1)
        top_t, top_q = placed[trail.edges[-1].child if trail.edges else trail.frame]
        self.top = (top_t[0], top_q[0])
        self.top_rotation = rotation_matrices(self.top[1]).T  # rows of positions times it: rotated by the top edge
        self.transforms = ClosedFormJointTransforms(tree, names)
        joints = _chain(tree, trail.start_link, trail.link)
        self.vectors = [_Step.of(joint, names) for joint in joints]
        self.fast = self._agrees()
        self._last: np.ndarray | None = None  # the previous row's position: a line's first segment of the next block
        self._lock = threading.Lock()

    def positions(self, values: np.ndarray) -> np.ndarray:
        """rows x 3, float64: the link's position in the trail's frame at each row. Composed bottom up on the
        position alone (each joint's rotation applied to a vector in closed form, three 3x3 products a joint), which
        agrees with composing the FK's joint transforms top down (checked at construction, `_agrees`) at about
        half the cost."""
        if not self.fast:
            return self.composed(values)
        with np.errstate(invalid="ignore", over="ignore"):
            position = np.zeros((len(values), 3))
            for step in reversed(self.vectors):
                position = step.apply(position, values)
            return position @ self.top_rotation + self.top[0]

    def composed(self, values: np.ndarray) -> np.ndarray:
        """The same positions from the FK's joint transforms, composed top down (`link_poses`): the reference
        `positions` is checked against."""
        return self.transforms.link_poses(values, self.trail.start_link, self.top)[self.trail.link][0]

    def _agrees(self) -> bool:
        """The bottom-up composition against the FK's transforms on probe values (every joint at each probe, and a
        row of mixed ones): a joint kind this code does not know keeps the reference, never a different path."""
        probes = probe_values(len(self.transforms.names))
        self.fast = True
        return bool(np.abs(self.positions(probes) - self.composed(probes)).max() <= 1e-9)

    def column(self, values: np.ndarray, left_out: np.ndarray | None) -> pa.Array:
        """The trail's rows for the lens: a list of one position (points) or of one two-point strip (line); null
        where the NaN policy leaves the row out. Blocks come in source order (Rerun's streams process chunks in
        sequence), which a line's segment across blocks relies on."""
        rows = len(values)
        here = self.positions(values).astype(np.float32)
        keep = np.ones(rows, dtype=bool) if left_out is None else ~left_out
        mask = None if left_out is None else pa.array(left_out)
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32))
        if self.trail.style == "points":
            return pa.ListArray.from_arrays(offsets, float_vectors(here), mask=mask)
        with self._lock:
            kept = np.flatnonzero(keep)
            before = np.empty_like(here)
            if len(kept):
                previous = here[kept[0]] if self._last is None else self._last
                before[kept] = np.vstack([previous[None], here[kept[:-1]]])
                self._last = here[kept[-1]].copy()
        points = np.stack([before, here], axis=1).reshape(-1, 3)
        strips = pa.ListArray.from_arrays(pa.array(np.arange(rows + 1, dtype=np.int32) * 2), float_vectors(points), type=STRIP_TYPE)
        return pa.ListArray.from_arrays(offsets, strips, mask=mask)


@dataclass(frozen=True)
class _Step:
    """One joint of a trail's chain, as it moves a position from its child frame into its parent's: p -> R_o(J(q) p)
    + t_o, with J a turn about the axis (Rodrigues: p + sin q (a x p) + (1 - cos q) a x (a x p)) or a slide along it."""

    column: int | None  # the joint's column in the value matrix; None: a joint no value drives (its origin only)
    turning: bool
    matrices: np.ndarray  # 3 x 9, [R_o | R_o K | R_o K^2] transposed (K: the axis's cross-product matrix); 3 x 3 R_o^T
    origin: np.ndarray  # t_o
    slide: np.ndarray  # R_o a, for a prismatic joint

    @classmethod
    def of(cls, joint: UrdfJoint, names: list[str]) -> _Step:
        rotation = rotation_matrices(np.array(quaternion_from_rpy(*joint.origin_rpy)))
        origin = np.array(joint.origin_xyz, dtype=np.float64)
        kind = joint.joint_type if joint.name in names else "fixed"
        axis = np.array(joint.axis if kind != "fixed" else (1.0, 0.0, 0.0), dtype=np.float64)
        axis /= np.linalg.norm(axis)
        if kind in ("revolute", "continuous"):
            cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
            matrices = np.hstack([rotation.T, (rotation @ cross).T, (rotation @ cross @ cross).T])
            return cls(names.index(joint.name), True, matrices, origin, np.zeros(3))
        column = names.index(joint.name) if kind == "prismatic" else None
        return cls(column, False, rotation.T, origin, rotation @ axis)

    def apply(self, position: np.ndarray, values: np.ndarray) -> np.ndarray:
        moved = position @ self.matrices
        if self.turning:
            angle = values[:, self.column, None]
            return moved[:, :3] + np.sin(angle) * moved[:, 3:6] + (1.0 - np.cos(angle)) * moved[:, 6:] + self.origin
        if self.column is not None:
            return moved + values[:, self.column, None] * self.slide + self.origin
        return moved + self.origin


def _chain(tree: UrdfTree, start: str, link: str) -> list:
    """The URDF joints from `start` down to `link`, top down (compile/trails.py checked that `start` is above it)."""
    parent_joint = {joint.child_link: joint for joint in tree.joints()}
    chain = []
    current = link
    while current != start:
        joint = parent_joint[current]
        chain.append(joint)
        current = joint.parent_link
    return chain[::-1]


def trail_lenses(component: str, trails: list[TrailPlan]) -> list[DeriveLens]:
    """The second stage's lenses: each trail's field of the compute lens's struct, on the trail's entity."""
    import rerun as rr
    from rerun.chunk import DeriveLens, Selector

    lenses = []
    for index, trail in enumerate(trails):
        descriptor = rr.Points3D.descriptor_positions() if trail.style == "points" else rr.LineStrips3D.descriptor_strips()
        lenses.append(DeriveLens(component, output_entity=trail.entity).to_component(descriptor, Selector(f".{trail_field(index)}[]")))
    return lenses


def trail_statics_stream(trails: tuple[TrailPlan, ...]) -> LazyChunkStream:
    """One static chunk per trail: the frame its positions are in (so the viewer moves it with that frame), its
    radius and its colour."""
    import rerun as rr
    from rerun.chunk import Chunk, LazyChunkStream

    chunks = []
    for trail in trails:
        archetype = rr.Points3D if trail.style == "points" else rr.LineStrips3D
        columns = [*rr.CoordinateFrame.columns(frame=[trail.frame])]
        columns += archetype.columns(radii=[TRAIL_RADIUS], colors=None if trail.color is None else [trail.color])
        chunks.append(Chunk.from_columns(trail.entity, indexes=[], columns=columns))
    return LazyChunkStream.from_iter(chunks)


def trail_time_ranges(trails: tuple[TrailPlan, ...]) -> list[rrb.VisibleTimeRange] | None:
    """The 3D views' visible time range on each trail's timelines: its window up to the time cursor (the widest
    window where trails share a timeline; from the start without one). The range is the view's: Rerun 0.41's
    blueprint sets it per view, and the other entities of a 3D view (the model's geometry, static; the transforms,
    resolved at the cursor) are drawn as without it. None without trails: the views as before."""
    import rerun.blueprint as rrb

    spans: dict[str, tuple[float | None, str]] = {}
    for trail in trails:
        for timeline in trail.timelines:
            kept = spans.get(timeline)
            if kept is None or (kept[0] is not None and (trail.window is None or trail.window > kept[0])):
                spans[timeline] = (trail.window, trail.window_unit)
    if not spans:
        return None
    ranges = []
    for timeline, (span, unit) in spans.items():
        if span is None:
            start = rrb.TimeRangeBoundary.infinite()
        elif unit == "rows":
            start = rrb.TimeRangeBoundary.cursor_relative(seq=-int(span))
        else:
            start = rrb.TimeRangeBoundary.cursor_relative(seconds=-span)
        ranges.append(rrb.VisibleTimeRange(timeline, start=start, end=rrb.TimeRangeBoundary.cursor_relative()))
    return ranges

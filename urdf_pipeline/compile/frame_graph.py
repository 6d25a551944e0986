"""The frame graph every stream will log, checked before writing: one root, every frame reaches it (else a frame
silently collapses onto the origin in the viewer). Linear in frames and edges; "did you mean" only for the first few."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import Hints, Where, closest, did_you_mean
from .context import CompileContext


@dataclass(frozen=True)
class FrameEdge:
    parent: str
    child: str
    origin: str  # "URDF 'panda' joint 'panda_joint1' (robot arm)" or "edges[0] at line 3"
    where: Where
    configured: bool = False  # written in the config (or a sidecar, or frames.assume_identity), not taken from a URDF


def _parents(ctx: CompileContext, edges: list[FrameEdge]) -> dict[str, FrameEdge]:
    """Each frame's parent edge (the first one); a self edge or a second parent is a problem."""
    parent_of: dict[str, FrameEdge] = {}
    for edge in edges:
        if edge.child == edge.parent:
            ctx.problems.add(f"edge from frame '{edge.parent}' to itself ({edge.origin})", edge.where)
            continue
        first = parent_of.get(edge.child)
        if first is not None:
            ctx.problems.add(
                f"frame '{edge.child}' has two parents: '{first.parent}' ({first.origin}) and '{edge.parent}' ({edge.origin}); a frame has exactly one parent",
                edge.where,
            )
            continue
        parent_of[edge.child] = edge
    return parent_of


def tops(parent_of: dict[str, FrameEdge], frames: list[str]) -> dict[str, str | tuple[str, ...]]:
    """Where each frame's walk up its parents ends: the top frame of its tree (a frame without a parent), or the cycle
    it runs into (a tuple, in walk order from the first frame of `frames` that reaches it). Each frame is walked once."""
    ends: dict[str, str | tuple[str, ...]] = {}
    for frame in frames:
        path: list[str] = []
        on_path: set[str] = set()
        current = frame
        while current not in ends and current in parent_of and current not in on_path:
            path.append(current)
            on_path.add(current)
            current = parent_of[current].parent
        if current in ends:
            end = ends[current]
        elif current in on_path:
            end = tuple(path[path.index(current) :])
        else:
            end = current  # no parent: the top of the tree
            ends[current] = current
        for visited in path:
            ends[visited] = end
    return ends


def check_frame_graph(ctx: CompileContext, edges: list[FrameEdge], urdf_frames: dict[str, Where], root: str, root_where: Where) -> None:
    problems = ctx.problems
    parent_of = _parents(ctx, edges)
    if root in parent_of:
        edge = parent_of[root]
        problems.add(f"root frame '{root}' must have no parent, but {edge.origin} gives it parent '{edge.parent}'", edge.where)
        return
    frames = sorted(set(urdf_frames) | {e.parent for e in edges} | {e.child for e in edges})
    ends = tops(parent_of, frames)
    reported_cycles: set[tuple[str, ...]] = set()
    hints = _Hints(urdf_frames, edges)
    for frame in frames:
        end = ends[frame]
        if isinstance(end, tuple):
            if end not in reported_cycles:
                reported_cycles.add(end)
                chain = " -> ".join([*end, end[0]])
                in_cycle = [parent_of[member] for member in end]
                culprit = next((e for e in in_cycle if e.configured), in_cycle[0])
                problems.add(f"frames form a cycle: {chain}; remove one of these edges", culprit.where)
        elif end == frame and frame != root:  # report only the top of each disconnected tree
            problems.add(hints.disconnected_message(frame, root), urdf_frames.get(frame) or hints.parent_where.get(frame) or root_where)


class _Hints:
    """What a disconnected frame's message says beyond the fact: a likely typo, and the config line to point at;
    computed once for all frames, the name comparisons for the first HINTED frames only."""

    def __init__(self, urdf_frames: dict[str, Where], edges: list[FrameEdge]) -> None:
        self.urdf_frames = urdf_frames
        self.strays = [e.child for e in edges if e.child not in urdf_frames and e.configured]
        self.parent_where: dict[str, Where] = {}  # a frame's first configured edge as a parent: the line to point at
        for edge in edges:
            if edge.configured:
                self.parent_where.setdefault(edge.parent, edge.where)
        self.hints = Hints()
        self.sorted_frames: list[str] | None = None

    def disconnected_message(self, frame: str, root: str) -> str:
        message = f"no edge connects frame '{frame}' to root '{root}'"
        hinted = self.hints.allowed()
        if frame in self.urdf_frames:
            message += f"; add a calibration edge with parent: {root} (or a frame that reaches it) and child: {frame}"
            stray = closest(frame, self.strays) if hinted else None
            if stray is not None:
                message += f" (edge child '{stray}' is in no URDF: a typo for '{frame}'?)"
        else:
            message += "; it is named only by an edge and by no URDF"
            if hinted:
                if self.sorted_frames is None:
                    self.sorted_frames = sorted(self.urdf_frames)
                message += did_you_mean(frame, self.sorted_frames)
        return message


def check_assume_identity(
    ctx: CompileContext, frames: list[tuple[str, Where]], edges: list[FrameEdge], urdf_frames: dict[str, Where], root: str
) -> list[str]:
    """The frames of `frames.assume_identity` that may get an identity edge from the root: named by a URDF or an edge,
    not the root, without a parent yet (one hanging from a disconnected tree needs its tree's top listed); problems for
    the others."""
    problems = ctx.problems
    parent_of: dict[str, FrameEdge] = {}
    for edge in edges:
        parent_of.setdefault(edge.child, edge)
    named = set(urdf_frames) | {e.parent for e in edges} | {e.child for e in edges}
    ends = tops(parent_of, [frame for frame, _ in frames if frame in parent_of])
    hint = Hints()
    accepted: list[str] = []
    for frame, where in frames:
        if frame == root:
            problems.add(f"'{frame}' is the root frame; frames.assume_identity lists frames to hang from it", where)
        elif frame not in named:
            said = hint(frame, named)
            problems.add(f"frame '{frame}' is named by no URDF and no edge; remove it from frames.assume_identity{said}", where)
        elif frame in parent_of:
            edge, top = parent_of[frame], ends[frame]
            if top == root:
                problems.add(
                    f"frame '{frame}' already reaches root '{root}' (its parent is '{edge.parent}', {edge.origin}); "
                    "remove it from frames.assume_identity",
                    where,
                )
            elif isinstance(top, tuple):
                problems.add(f"frame '{frame}' already has parent '{edge.parent}' ({edge.origin}), in a cycle of frames; remove it", where)
            else:
                problems.add(
                    f"frame '{frame}' already has parent '{edge.parent}' ({edge.origin}); assume_identity hangs a frame without "
                    f"a parent from the root: list '{top}', the top of its tree, instead",
                    where,
                )
        else:
            accepted.append(frame)
    return accepted

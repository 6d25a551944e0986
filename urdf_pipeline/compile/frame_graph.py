"""The frame graph every stream will log, checked before writing: one root, every frame reaches it.

Without this check a frame with no edge to the root silently collapses onto the origin in the viewer.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import Where, closest, did_you_mean
from .context import CompileContext


@dataclass(frozen=True)
class FrameEdge:
    parent: str
    child: str
    origin: str  # "URDF 'panda' joint 'panda_joint1' (robot arm)" or "edges[0] at line 3"
    where: Where
    configured: bool = False  # written in the config (or a sidecar, or frames.assume_identity), not taken from a URDF


def check_frame_graph(ctx: CompileContext, edges: list[FrameEdge], urdf_frames: dict[str, Where], root: str, root_where: Where) -> None:
    problems = ctx.problems
    parent_of: dict[str, FrameEdge] = {}
    for edge in edges:
        if edge.child == edge.parent:
            problems.add(f"edge from frame '{edge.parent}' to itself ({edge.origin})", edge.where)
            continue
        first = parent_of.get(edge.child)
        if first is not None:
            problems.add(
                f"frame '{edge.child}' has two parents: '{first.parent}' ({first.origin}) and '{edge.parent}' ({edge.origin}); a frame has exactly one parent",
                edge.where,
            )
            continue
        parent_of[edge.child] = edge
    if root in parent_of:
        edge = parent_of[root]
        problems.add(f"root frame '{root}' must have no parent, but {edge.origin} gives it parent '{edge.parent}'", edge.where)
        return
    frames = set(urdf_frames) | {e.parent for e in edges} | {e.child for e in edges}
    reported_cycles: set[str] = set()
    for frame in sorted(frames):
        seen: list[str] = []
        current = frame
        while current in parent_of and current not in seen:
            seen.append(current)
            current = parent_of[current].parent
        if current == root:
            continue
        if current in seen:  # a cycle
            cycle = seen[seen.index(current) :]
            key = min(cycle)
            if key not in reported_cycles:
                reported_cycles.add(key)
                chain = " -> ".join([*cycle, current])
                in_cycle = [parent_of[frame] for frame in cycle]
                culprit = next((e for e in in_cycle if e.configured), in_cycle[0])
                problems.add(f"frames form a cycle: {chain}; remove one of these edges", culprit.where)
            continue
        if frame != current:
            continue  # report only the top of each disconnected tree
        problems.add(
            _disconnected_message(current, root, urdf_frames, edges), urdf_frames.get(current) or _where_for(current, edges, root_where)
        )


def _disconnected_message(frame: str, root: str, urdf_frames: dict[str, Where], edges: list[FrameEdge]) -> str:
    message = f"no edge connects frame '{frame}' to root '{root}'"
    if frame in urdf_frames:
        message += f"; add a calibration edge with parent: {root} (or a frame that reaches it) and child: {frame}"
        strays = [e.child for e in edges if e.child not in urdf_frames and e.configured]
        stray = closest(frame, strays)
        if stray is not None:
            message += f" (edge child '{stray}' is in no URDF: a typo for '{frame}'?)"
    else:
        message += "; it is named only by an edge and by no URDF" + did_you_mean(frame, sorted(urdf_frames))
    return message


def _where_for(frame: str, edges: list[FrameEdge], fallback: Where) -> Where:
    for edge in edges:
        if edge.parent == frame and edge.configured:
            return edge.where
    return fallback


def check_assume_identity(
    ctx: CompileContext, frames: list[tuple[str, Where]], edges: list[FrameEdge], urdf_frames: dict[str, Where], root: str
) -> list[str]:
    """The frames of `frames.assume_identity` that may get an identity edge from the root; problems for the others.

    A listed frame must be named by a URDF or an edge, must not be the root and must have no parent yet: a frame
    that already reaches the root needs no assumption, and one hanging from a disconnected tree needs its tree's top listed.
    """
    problems = ctx.problems
    parent_of: dict[str, FrameEdge] = {}
    for edge in edges:
        parent_of.setdefault(edge.child, edge)
    named = set(urdf_frames) | {e.parent for e in edges} | {e.child for e in edges}
    accepted: list[str] = []
    for frame, where in frames:
        if frame == root:
            problems.add(f"'{frame}' is the root frame; frames.assume_identity lists frames to hang from it", where)
        elif frame not in named:
            hint = did_you_mean(frame, sorted(named))
            problems.add(f"frame '{frame}' is named by no URDF and no edge; remove it from frames.assume_identity{hint}", where)
        elif frame in parent_of:
            edge = parent_of[frame]
            top, seen = frame, [frame]
            while top in parent_of and parent_of[top].parent not in seen:
                top = parent_of[top].parent
                seen.append(top)
            if top == root:
                problems.add(
                    f"frame '{frame}' already reaches root '{root}' (its parent is '{edge.parent}', {edge.origin}); "
                    "remove it from frames.assume_identity",
                    where,
                )
            else:
                problems.add(
                    f"frame '{frame}' already has parent '{edge.parent}' ({edge.origin}); assume_identity hangs a frame without "
                    f"a parent from the root: list '{top}', the top of its tree, instead",
                    where,
                )
        else:
            accepted.append(frame)
    return accepted

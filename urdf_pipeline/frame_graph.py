"""The frame graph every stream will log, checked before writing: one root, every frame reaches it.

Without this check a frame with no edge to the root silently collapses onto the origin in the viewer.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

from .errors import Problems, Where


@dataclass(frozen=True)
class FrameEdge:
    parent: str
    child: str
    origin: str  # "URDF 'panda' joint 'panda_joint1' (robot arm)" or "edges[0]"
    where: Where


def check_frame_graph(edges: list[FrameEdge], urdf_frames: dict[str, Where], root: str, root_where: Where, problems: Problems) -> None:
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
                culprit = next((e for e in in_cycle if e.origin.startswith("edges[")), in_cycle[0])
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
        strays = [e.child for e in edges if e.child not in urdf_frames and e.origin.startswith("edges[")]
        close = difflib.get_close_matches(frame, strays, n=1, cutoff=0.85)
        if close:
            message += f" (edge child '{close[0]}' is in no URDF: a typo for '{frame}'?)"
    else:
        close = difflib.get_close_matches(frame, sorted(urdf_frames), n=1, cutoff=0.6)
        message += "; it is named only by an edge and by no URDF" + (f" (did you mean '{close[0]}'?)" if close else "")
    return message


def _where_for(frame: str, edges: list[FrameEdge], fallback: Where) -> Where:
    for edge in edges:
        if edge.parent == frame and edge.origin.startswith("edges["):
            return edge.where
    return fallback

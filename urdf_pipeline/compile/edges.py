"""Compile calibration edges (static, fixed_chain, a bag's /tf_static, temporal, assumed identity) and the frame graph's edge list."""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..config import EdgeSpec
from ..errors import Hints, warn
from ..plan import EdgePlan, FixedChain, RobotPlan, TemporalEdgePlan
from ..urdf import NoFixedChain, UrdfModel, compose_chain, find_fixed_chain, normalized_quaternion, quaternion_from_rpy
from .bag_edges import BagReads, compile_bag_edge, compile_tf_edge
from .context import CompileContext, SourceNames
from .frame_graph import FrameEdge, check_assume_identity
from .temporal_edges import TemporalEntities, compile_temporal_edge


@dataclass(frozen=True)
class CompiledEdges:
    """The config's edges by kind, in config order; `broken` are those that failed (reported; they still count in
    the frame graph so one mistake is one error)."""

    static: tuple[EdgePlan, ...]  # static and fixed_chain edges, logged on /calibration
    temporal: tuple[TemporalEdgePlan, ...]
    broken: tuple[EdgeSpec, ...]


def compile_edges(
    ctx: CompileContext,
    specs: list[EdgeSpec],
    robots: list[RobotPlan] | None,
    models: Mapping[str, UrdfModel],
    sources: SourceNames,
) -> CompiledEdges:
    """Static and fixed_chain edges, temporal edges, and the edges that failed. `robots` is None when frame names
    cannot be traced to robots (a robot failed, or prefixes collide): fixed chains are then skipped, already in error."""
    problems = ctx.problems
    edges: list[EdgePlan] = []
    temporal: list[TemporalEdgePlan] = []
    broken: list[EdgeSpec] = []
    entities = TemporalEntities()
    owners = _Owners(robots or [])
    bags = BagReads()
    for edge in specs:
        spec = edge.spec
        if "tf_static" in spec:
            from_bag = compile_bag_edge(ctx, edge, bags)
            if from_bag is None:
                broken.append(edge)
            else:
                edges.append(from_bag)
            continue
        if "source" in spec or "tf" in spec:
            compiled = (
                compile_temporal_edge(ctx, edge, sources, entities)
                if "source" in spec
                else compile_tf_edge(ctx, edge, sources, entities, bags)
            )
            if compiled is not None:
                temporal.append(compiled)
            else:
                broken.append(edge)
            continue
        if "fixed_chain" in spec:
            chained = _fixed_chain_edge(ctx, edge, owners, models) if robots is not None else None
            if chained is not None:
                edges.append(chained)
            else:
                broken.append(edge)
            continue
        if "quaternion_xyzw" in spec:
            quaternion = normalized_quaternion(tuple(spec["quaternion_xyzw"]))
            if quaternion is None:
                problems.add("quaternion_xyzw is zero; write [0, 0, 0, 1] for no rotation", edge.where("quaternion_xyzw"))
                broken.append(edge)
                continue
        else:
            rpy = spec["rpy"] if "rpy" in spec else [math.radians(v) for v in spec["rpy_deg"]]
            quaternion = quaternion_from_rpy(*rpy)
        translation = tuple(float(v) for v in spec["translation"])
        edges.append(EdgePlan(spec["parent"], spec["child"], translation, quaternion, edge.where(), label=edge.label))  # type: ignore[arg-type]
    return CompiledEdges(tuple(edges), tuple(temporal), tuple(broken))


class _Owners:
    """Which robot's URDF emits a frame (a link name with its frame_prefix applied): the first robot, in config order,
    that has it. Made once for all edges, so each look-up is a dict's, whatever the robots' size."""

    def __init__(self, robots: list[RobotPlan]) -> None:
        self.by_frame: dict[str, RobotPlan] = {}
        for robot in robots:
            for link in robot.links:
                self.by_frame.setdefault(robot.frame_prefix + link, robot)
        self.hints = Hints()  # "did you mean", for the first unknown frames (with the looser cutoff of fixed chains)
        self.sorted: list[str] | None = None

    def hint(self, frame: str) -> str:
        if not self.hints.allowed():
            return ""
        if self.sorted is None:
            self.sorted = sorted(self.by_frame)
        close = difflib.get_close_matches(frame, self.sorted, n=1, cutoff=0.6)
        return f" (did you mean '{close[0]}'?)" if close else ""


def _fixed_chain_edge(ctx: CompileContext, edge: EdgeSpec, robots: _Owners, models: Mapping[str, UrdfModel]) -> EdgePlan | None:
    problems = ctx.problems
    spec = edge.spec
    start, end = spec["fixed_chain"]["from"], spec["fixed_chain"]["to"]
    owners = {}
    for key in ("from", "to"):
        frame = spec["fixed_chain"][key]
        owners[key] = robots.by_frame.get(frame)
        if owners[key] is None:
            problems.add(f"fixed_chain.{key} '{frame}' is a link of no URDF{robots.hint(frame)}", edge.where("fixed_chain", key))
    robot, other = owners["from"], owners["to"]
    if robot is None or other is None:
        return None
    prefix = robot.frame_prefix
    if other is not robot:
        problems.add(
            f"no fixed chain from {start} to {end}; stuck at {start}: '{end}' is a link of robot '{other.key}', "
            f"'{start}' of robot '{robot.key}'",
            edge.where("fixed_chain"),
        )
        return None
    model = models.get(robot.key)
    if model is None:
        return None
    try:
        joints = find_fixed_chain(model, start[len(prefix) :], end[len(prefix) :])
    except NoFixedChain as stuck:
        if stuck.blocking is not None:
            reason = (
                f"the next joint toward {end}, '{stuck.blocking.name}', is {stuck.blocking.type}, not fixed "
                f"({prefix}{stuck.stuck} is the deepest link toward {end} that fixed joints reach)"
            )
        elif stuck.end_is_above:
            reason = f"'{end}' is above '{start}' in URDF '{model.name}', not below it; swap from and to"
        else:
            reason = f"'{end}' is not below '{start}' in URDF '{model.name}'"
        problems.add(f"no fixed chain from {start} to {end}; stuck at {prefix}{stuck.stuck}: {reason}", edge.where("fixed_chain"))
        return None
    translation, quaternion = compose_chain(joints)
    chain = FixedChain(robot.key, start, end, tuple(joint.name for joint in joints))
    return EdgePlan(spec["parent"], spec["child"], translation, quaternion, edge.where(), "fixed_chain", edge.label, chain)


def assumed_identity_edges(ctx: CompileContext, robots: list[RobotPlan], graph: list[FrameEdge], root: str) -> list[EdgePlan]:
    """frames.assume_identity: an identity edge root -> frame for each listed frame, with a warning naming it."""
    listed = ctx.data.get("frames", {}).get("assume_identity", [])
    if not listed:
        return []
    wheres = {frame: ctx.where("frames", "assume_identity", index) for index, frame in enumerate(listed)}
    accepted = check_assume_identity(ctx, list(wheres.items()), graph, urdf_frames(robots), root)
    result = []
    for frame in accepted:
        where = wheres[frame]
        warn(
            f"frame '{frame}' has no calibration; logging an identity edge from root '{root}' (frames.assume_identity): "
            "its pose is assumed, not measured",
            where,
        )
        label = where.path
        result.append(EdgePlan(root, frame, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), where, "assume_identity", label))
    return result


def frame_edges(
    robots: Sequence[RobotPlan],
    edges: Sequence[EdgePlan],
    temporal: Sequence[TemporalEdgePlan],
    models: Mapping[str, UrdfModel],
    broken: Sequence[EdgeSpec] = (),
) -> list[FrameEdge]:
    # A temporal edge may drive the child of a URDF floating/planar joint (a floating pelvis) when it has the joint's
    # parent: like the FK over a moving joint's rest pose, the temporal value overrides the joint's static identity.
    driven = {(edge.parent, edge.child) for edge in temporal}
    result = []
    for robot in robots:
        overridable = set()
        if driven:
            model = models.get(robot.key)
            overridable = {j.name for j in model.joints if j.type in ("floating", "planar")} if model is not None else set()
        for joint, parent, child in robot.joint_links:
            if joint in overridable and (robot.frame_prefix + parent, robot.frame_prefix + child) in driven:
                continue
            result.append(
                FrameEdge(
                    robot.frame_prefix + parent,
                    robot.frame_prefix + child,
                    f"URDF '{robot.robot_name}' joint '{joint}' of robot '{robot.key}'",
                    robot.where,
                )
            )
    result += [FrameEdge(edge.parent, edge.child, f"{edge.label} at line {edge.where.line}", edge.where, True) for edge in edges]
    result += [
        FrameEdge(edge.parent, edge.child, f"temporal {edge.label} at line {edge.where.line}", edge.where, True) for edge in temporal
    ]
    result += [
        FrameEdge(edge.spec["parent"], edge.spec["child"], f"{edge.label} at line {edge.where().line}", edge.where(), True)
        for edge in broken
    ]
    return result


def urdf_frames(robots: list[RobotPlan]) -> dict[str, Any]:
    return {robot.frame_prefix + link: robot.where for robot in robots for link in robot.links}

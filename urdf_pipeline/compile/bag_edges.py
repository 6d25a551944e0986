"""Edges a ROS 2 bag carries (`tf_static:` as a static `EdgePlan`, `tf:` as a temporal one), read here (metadata-
sized, in a child process) so they join the frame graph like any edge and `validate` refuses what `run` would. Each
bag and topic is read once per config, however many edges name it."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TypeVar

from ..config import EdgeSpec
from ..confine import refuse_url
from ..errors import UserError, Where, did_you_mean, listing, quoted, shown
from ..plan import EdgePlan, TemporalEdgePlan
from ..sources import GLOB, BagTransform, static_transforms, tf_pairs
from ..urdf import normalized_quaternion
from .context import CompileContext, SourceNames
from .temporal_edges import TemporalEntities

T = TypeVar("T")


class BagReads:
    """The bags' static transforms read so far in one config, by (file, topic); a failed read is kept as its error."""

    def __init__(self) -> None:
        self.read: dict[tuple[Path, str], dict[str, BagTransform] | UserError] = {}
        self.pairs: dict[tuple[Path, str], tuple[dict[str, list[str]], bool] | UserError] = {}


def compile_bag_edge(ctx: CompileContext, edge: EdgeSpec, reads: BagReads) -> EdgePlan | None:
    """The edge's transform from the bag, or None with the problem reported at the edge's key that is wrong."""
    spec = edge.spec
    topic = spec.get("topic", "/tf_static")
    try:
        transforms = _transforms(ctx, edge, topic, reads)
    except UserError as exc:
        ctx.problems.extend(exc)
        return None
    if transforms is None:
        return None  # the bag's topic failed at an earlier edge, said there
    child, parent = spec["child"], spec["parent"]
    found = transforms.get(child)
    file_name = Path(spec["tf_static"]).name
    if found is None:
        _no_child_frame(ctx, topic, file_name, child, transforms, edge.where("child"))
        return None
    if found.parent != parent:
        ctx.problems.add(
            f"{quoted(topic)} of {file_name} places {quoted(child)} in {quoted(found.parent)}, not in {quoted(parent)}; "
            f"write parent: {shown(found.parent)}",
            edge.where("parent"),
        )
        return None
    quaternion = normalized_quaternion(found.quaternion_xyzw) if all(map(math.isfinite, found.quaternion_xyzw)) else None
    if quaternion is None or not all(map(math.isfinite, found.translation)):
        ctx.problems.add(
            f"{quoted(topic)} of {file_name} gives {quoted(child)} a NaN, infinite or all-zero transform "
            f"(translation {list(found.translation)}, quaternion_xyzw {list(found.quaternion_xyzw)}); fix the bag's publisher",
            edge.where("tf_static"),
        )
        return None
    return EdgePlan(parent, child, found.translation, quaternion, edge.where(), label=edge.label)


def _transforms(ctx: CompileContext, edge: EdgeSpec, topic: str, reads: BagReads) -> dict[str, BagTransform] | None:
    where = edge.where("tf_static")
    name = str(edge.spec["tf_static"])
    refuse_url(name, "MCAP file", where)
    path = ctx.confinement.check_read(Path(os.path.abspath(ctx.config_dir / name)), "MCAP file", where)
    if not path.is_file():
        raise UserError(f"MCAP file not found: {path} (paths are relative to the config file)", where)
    return _read_once(
        reads.read, (path, topic), lambda: static_transforms(path, topic, edge.where("topic") if "topic" in edge.spec else where)
    )


def _read_once(cache: dict[tuple[Path, str], T | UserError], key: tuple[Path, str], read: Callable[[], T]) -> T | None:
    """`read()` once per bag and topic: its error raised the first time, None after (said once, at the first edge)."""
    if key not in cache:
        try:
            cache[key] = read()
        except UserError as exc:
            cache[key] = exc
            raise
    known = cache[key]
    return None if isinstance(known, UserError) else known


def compile_tf_edge(
    ctx: CompileContext, edge: EdgeSpec, sources: SourceNames, entities: TemporalEntities, reads: BagReads
) -> TemporalEdgePlan | None:
    """`{parent: odom, child: base_link, tf: SOURCE}`: the child's transforms on the /tf topic of an MCAP source's bag,
    on that source's timeline, so the base and the arm's joint states line up. The frames are checked at compile
    against the first transforms of a plain local bag (a glob's or a remote one's in the data pass: zero rows)."""
    spec = edge.spec
    name, topic = spec["tf"], spec.get("topic", "/tf")
    if name not in sources:
        if name not in ctx.source_names:
            ctx.problems.add(
                f"no source named {quoted(name)}; sources are: {listing(sorted(ctx.source_names), empty='none')}", edge.where("tf")
            )
        return None  # else the source itself is broken and already reported
    source = ctx.data["sources"][name]
    if "mcap" not in source:
        ctx.problems.add(
            f"source {quoted(name)} is no MCAP source; tf: names an mcap source (a ROS 2 bag), whose file holds {topic}", edge.where("tf")
        )
        return None
    if not _frames_match(ctx, edge, str(source["mcap"]), topic, reads):
        return None
    return TemporalEdgePlan(
        parent=spec["parent"],
        child=spec["child"],
        source=name,
        translation_names=("translation.x", "translation.y", "translation.z"),
        quaternion_names=("rotation.x", "rotation.y", "rotation.z", "rotation.w"),
        translation_indices=(0, 1, 2),
        quaternion_indices=(3, 4, 5, 6),
        entity=entities.entity_for(spec["child"]),
        label=edge.label,
        where=edge.where(),
        tf_topic=topic,
    )


def _frames_match(ctx: CompileContext, edge: EdgeSpec, file: str, topic: str, reads: BagReads) -> bool:
    """The bag's first transforms give `child` with `parent`; True when they do, or when only the data can tell."""
    if GLOB.search(file) or "{" in file or "://" in file or not ctx.opens_sources:
        return True
    path = Path(os.path.abspath(ctx.config_dir / file))
    try:
        known = _read_once(
            reads.pairs, (path, topic), lambda: tf_pairs(path, topic, edge.where("topic") if "topic" in edge.spec else edge.where("tf"))
        )
    except UserError as exc:
        ctx.problems.extend(exc)
        return False
    if known is None:
        return False
    pairs, complete = known
    child, parent = edge.spec["child"], edge.spec["parent"]
    if child not in pairs:
        if not complete:
            return True  # not among the first transforms: the data pass says if it never comes
        _no_child_frame(ctx, topic, path.name, child, pairs, edge.where("child"))
        return False
    others = [other for other in pairs[child] if other != parent]
    if others:
        fix = f"write parent: {shown(others[0])}" if len(pairs[child]) == 1 else "a frame has one parent; fix the bag's publishers"
        ctx.problems.add(
            f"{quoted(topic)} of {path.name} places {quoted(child)} in {quoted(others[0])}, not in {quoted(parent)}; {fix}",
            edge.where("parent"),
        )
        return False
    return True


def _no_child_frame(ctx: CompileContext, topic: str, file_name: str, child: str, frames: Iterable[str], where: Where) -> None:
    """A /tf or /tf_static edge's child the bag has no transform for: the bag's child frames, and the closest one."""
    ctx.problems.add(
        f"{quoted(topic)} of {file_name} has no transform for child frame {quoted(child)}{did_you_mean(child, frames)}; its child "
        f"frames: {listing(sorted(frames), empty='none')}",
        where,
    )

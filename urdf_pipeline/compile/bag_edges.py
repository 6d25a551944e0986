"""Static edges a ROS 2 bag carries on /tf_static: `{parent: base_link, child: camera_link, tf_static: run.mcap}`.

The bag's transform for `child` becomes an ordinary static `EdgePlan`, read here (metadata-sized, in a child process:
`sources.static_transforms`), so it joins the frame graph like any edge and `validate` refuses what `run` would. Each
bag and topic is read once per config, however many edges name it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from ..config import EdgeSpec
from ..confine import refuse_url
from ..errors import UserError, closest, listing, quoted, shown
from ..plan import EdgePlan
from ..sources import BagTransform, static_transforms
from ..urdf import normalized_quaternion
from .context import CompileContext


class BagReads:
    """The bags' static transforms read so far in one config, by (file, topic); a failed read is kept as its error."""

    def __init__(self) -> None:
        self.read: dict[tuple[Path, str], dict[str, BagTransform] | UserError] = {}


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
        close = closest(child, transforms)
        hint = f" (did you mean {quoted(close)}?)" if close is not None else ""
        ctx.problems.add(
            f"{quoted(topic)} of {file_name} has no transform for child frame {quoted(child)}{hint}; its child frames: "
            f"{listing(sorted(transforms), empty='none')}",
            edge.where("child"),
        )
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
    key = (path, topic)
    if key not in reads.read:
        try:
            reads.read[key] = static_transforms(path, topic, edge.where("topic") if "topic" in edge.spec else where)
        except UserError as exc:
            reads.read[key] = exc
            raise
    known = reads.read[key]
    return None if isinstance(known, UserError) else known

"""A robot's `appearance` (its drawn colour) and `compare` (a commanded copy of a measured robot), checked once every
robot has compiled: the copy must name another robot, not itself a copy, with the same URDF text and driven joints."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from typing import Any

from ..errors import listing, quoted, shown
from ..plan import Comparison, RobotPlan
from ..urdf import UrdfModel
from .context import CompileContext
from .units import FACTORS

_QUANTITY = re.compile(r"^\s*([0-9.eE+-]+)\s*([a-z]+)\s*$")  # the schema's pattern already holds: NUMBER UNIT
DEFAULT_THRESHOLD = {"angle": "1 deg", "length": "1 mm"}


def appearance_of(spec: dict[str, Any]) -> tuple[float, float, float, float] | None:
    """The schema-checked `appearance:` as RGBA in 0..1; None: the URDF's own materials."""
    written = spec.get("appearance")
    if written is None:
        return None
    red, green, blue = (float(c) for c in written["color"])
    return (red, green, blue, float(written.get("opacity", 1.0)))


def _threshold(written: dict[str, str]) -> tuple[dict[str, tuple[float, str]], str]:
    """By kind (angle, length): (URDF units, the unit written), and the text, of a schema-checked threshold, its
    defaults filled in."""
    parts = {**DEFAULT_THRESHOLD, **written}
    values: dict[str, tuple[float, str]] = {}
    for kind, text in parts.items():
        match = _QUANTITY.match(text)
        assert match is not None, text  # the schema's pattern
        values[kind] = (float(match.group(1)) * FACTORS[match.group(2)], match.group(2))
    return values, f"{{angle: {parts['angle'].strip()}, length: {parts['length'].strip()}}}"


def with_comparisons(ctx: CompileContext, robots: list[RobotPlan], models: dict[str, UrdfModel]) -> list[RobotPlan]:
    """The robots with their `compare:` resolved; every refusal added to ctx.problems, located at the key at fault."""
    by_key = {robot.key: robot for robot in robots}
    specs: dict[str, Any] = ctx.data["robots"]
    resolved: list[RobotPlan] = []
    for robot in robots:
        written = specs[robot.key].get("compare")
        if written is None:
            resolved.append(robot)
            continue
        measured = _measured(ctx, robot, written["robot"], by_key, specs)
        if measured is None:
            resolved.append(robot)
            continue
        values, text = _threshold(written.get("threshold", {}))
        infinite = [kind for kind, (value, _) in values.items() if not math.isfinite(value)]
        if infinite:  # 1e999 deg: a number beyond a float's range, which the schema's NUMBER UNIT pattern lets through
            for kind in infinite:
                ctx.problems.add(
                    f"threshold {quoted(written['threshold'][kind])} is beyond a float's range: write a finite number",
                    ctx.where("robots", robot.key, "compare", "threshold", kind),
                )
            resolved.append(robot)
            continue
        kinds = {joint.name: joint.type for joint in models[robot.key].joints}
        per_joint = [values["length" if kinds[c.joint] == "prismatic" else "angle"] for c in robot.channels]
        comparison = Comparison(
            measured.key, values["angle"][0], values["length"][0], text, tuple(v for v, _ in per_joint), tuple(u for _, u in per_joint)
        )
        resolved.append(replace(robot, compare=comparison))
    return resolved


def _measured(ctx: CompileContext, copy: RobotPlan, key: str, by_key: dict[str, RobotPlan], specs: dict[str, Any]) -> RobotPlan | None:
    """The measured robot a copy names, when the two can be compared joint for joint; else None after a located problem."""
    where = ctx.where("robots", copy.key, "compare", "robot")
    if key == copy.key:
        ctx.problems.add(f"robot '{shown(key)}' is compared with itself; name the measured robot whose copy this is", where)
        return None
    if key not in specs:
        ctx.problems.add(f"no robot named '{shown(key)}' to compare with; robots are: {listing(list(specs))}", where)
        return None
    if "compare" in specs[key]:
        ctx.problems.add(f"robot '{shown(key)}' is itself a copy (it has compare:); compare with the measured robot it names", where)
        return None
    measured = by_key.get(key)
    if measured is None:
        return None  # it failed to compile, reported by itself
    if measured.urdf_sha256 != copy.urdf_sha256:
        ctx.problems.add(
            f"robot '{copy.key}' ({copy.urdf_path.name}, sha256 {copy.urdf_sha256[:12]}) and robot '{shown(key)}' "
            f"({measured.urdf_path.name}, sha256 {measured.urdf_sha256[:12]}) have different URDF texts; a copy must use the measured robot's URDF",
            where,
        )
        return None
    ours, theirs = {c.joint for c in copy.channels}, {c.joint for c in measured.channels}
    if ours != theirs or not ours:
        only_copy, only_measured = sorted(ours - theirs), sorted(theirs - ours)
        detail = "; ".join(
            part
            for part in (
                f"only '{copy.key}' drives {listing(only_copy)}" if only_copy else "",
                f"only '{shown(key)}' drives {listing(only_measured)}" if only_measured else "",
            )
            if part
        )
        ctx.problems.add(
            f"robots '{copy.key}' and '{shown(key)}' must drive the same joints to be compared: {detail or 'neither drives a joint'}",
            where,
        )
        return None
    if not _rows_match(ctx, copy, measured):
        return None
    return measured


# Keys that choose which values of a file a source reads; two sources equal but for them read the same rows.
_VALUE_KEYS = ("feature", "column", "names")


def _rows_match(ctx: CompileContext, copy: RobotPlan, measured: RobotPlan) -> bool:
    """Rows are compared one to one, in order: both robots read one source, or two LeRobot features or parquet
    columns of the same episodes or file (the same rows). Matching by time (two topics) is refused, not guessed."""
    if copy.source == measured.source:
        return True
    sources: dict[str, Any] = ctx.data["sources"]
    ours, theirs = sources[copy.source or ""], sources[measured.source or ""]
    kind = next((k for k in ("lerobot", "parquet") if k in ours and k in theirs), None)
    same = {k: v for k, v in ours.items() if k not in _VALUE_KEYS} == {k: v for k, v in theirs.items() if k not in _VALUE_KEYS}
    if kind is not None and same:
        return True
    ctx.problems.add(
        f"robot '{copy.key}' reads source '{shown(copy.source or '')}' and robot '{measured.key}' reads "
        f"'{shown(measured.source or '')}', whose rows cannot be matched one to one; compare robots driven by one source, "
        "or by two features of one LeRobot dataset (or two columns of one parquet file) with the same episodes and index",
        ctx.where("robots", copy.key, "joints", "source"),
    )
    return False

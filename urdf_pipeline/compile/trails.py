"""`trails:` -> `TrailPlan`s: each trail's robot, link, frame and window checked before anything is written. A trail
is composed at run from the frame down to the link (static edges, then the URDF's joints), so the frame must be above
the link with no temporal edge between (its pose comes from rows the robot's FK pass does not read)."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

from ..errors import Where, did_you_mean, listing, quoted
from ..plan import EdgePlan, RobotPlan, SourcePlan, TemporalEdgePlan, TrailPlan, WindowUnit
from ..sources import INT64_MAX  # a timeline's values: nanoseconds on a time timeline, rows on a sequence timeline
from .context import CompileContext

TRAILS_FOLDER = "trails"  # a trail's entity: <entity_path_prefix>/trails/<link>
_WINDOW = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(ms|s|min|rows?)\s*$")
_SECONDS = {"ms": 1e-3, "s": 1.0, "min": 60.0}


def parse_window(text: str) -> tuple[float, WindowUnit] | None:
    """`2 s`, `500 ms`, `1.5 min` (seconds) or `200 rows` (rows); None when it is neither, or not above 0. A float
    either way (a number of 400 digits is inf): `window_beyond` says whether a timeline can hold it."""
    match = _WINDOW.match(text)
    if match is None or float(match.group(1)) <= 0:
        return None
    number, unit = float(match.group(1)), match.group(2)
    if unit.startswith("row"):
        return (number, "rows") if number.is_integer() or math.isinf(number) else None
    return number * _SECONDS[unit], "s"


def window_beyond(span: float, unit: WindowUnit) -> str | None:
    """Why a parsed window is more (or less) than a timeline can hold, or None. Rerun's blueprint stores the window as
    an int64 offset from the time cursor, in nanoseconds as `int(seconds * 1e9)` (its TimeInt) or in rows: a longer
    one would be dropped from the blueprint with a warning, or stop the run."""
    if unit == "rows":
        return "more rows than a sequence timeline holds (below 2^63)" if not span < 2**63 else None
    nanos = span * 1e9
    if not nanos < INT64_MAX:  # inf from a number of 400 digits too
        return f"longer than a time timeline holds (int64 nanoseconds: at most {INT64_MAX // 10**9:,} s, about 292 years)"
    if int(nanos) < 1:
        return "shorter than 1 ns, the finest step of a time timeline"
    return None


def source_timelines(source: SourcePlan) -> tuple[tuple[str, str], ...]:
    """(timeline, kind) of the rows a source gives, as its kind's reader names them; () when only the data knows."""
    index = getattr(source, "index", None)
    if index is not None and hasattr(index, "column"):
        return ((index.column, index.kind),)
    kind = type(source).__name__
    if kind == "Hdf5SourcePlan":
        return (("row_index", "sequence"),)
    if kind == "LeRobotSourcePlan":  # and, from its `timestamp` column, the duration timeline `time` (sources/lerobot.py)
        return (("frame_index", "sequence"), *((("time", "duration"),) if getattr(source, "timed", False) else ()))
    timeline = getattr(source, "timeline", None)
    return ((timeline, "timestamp"),) if isinstance(timeline, str) else ()


def spec_timelines(spec: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    """The same from a source's config entry, for `validate --no-data`: a file's `index:` (a name: a sequence; or
    `{sequence|timestamp|duration: column}`), a LeRobot dataset's frame_index and time (as LeRobot writes every
    dataset); () for the kinds whose timeline only the compiled source knows."""
    if "lerobot" in spec:
        return (("frame_index", "sequence"), ("time", "duration"))
    index = spec.get("index") if ("parquet" in spec or "csv" in spec) else None
    if isinstance(index, str):
        return ((index, "sequence"),)
    if isinstance(index, Mapping) and len(index) >= 1:
        kind = next(key for key in ("sequence", "timestamp", "duration", "") if key in index or not key)
        return ((str(index[kind]), kind),) if kind else ()
    return ()


class _Graph:
    """Each frame's parent, as the trails walk it: URDF joints, static edges, temporal edges."""

    def __init__(self, robots: Sequence[RobotPlan], edges: Sequence[EdgePlan], temporal: Sequence[TemporalEdgePlan]) -> None:
        self.temporal = {edge.child: edge for edge in temporal}
        self.static = {edge.child: edge for edge in edges}
        self.joint_parent: dict[str, tuple[RobotPlan, str]] = {}  # prefixed child link -> (robot, unprefixed parent link)
        for robot in robots:
            for _, parent, child in robot.joint_links:
                self.joint_parent[robot.frame_prefix + child] = (robot, parent)
        self.frames = sorted(
            {robot.frame_prefix + link for robot in robots for link in robot.links}
            | {e.parent for e in edges}
            | {e.parent for e in temporal}
        )


def compile_trails(
    ctx: CompileContext,
    robots: Sequence[RobotPlan],
    edges: Sequence[EdgePlan],
    temporal: Sequence[TemporalEdgePlan],
    root: str,
    timelines: Mapping[str, tuple[tuple[str, str], ...]],
) -> tuple[TrailPlan, ...]:
    """Every trail of the config; problems added to ctx. `timelines`: each source's (timeline, kind), from its plan
    (`source_timelines`) or, without data, its config entry (`spec_timelines`); a window is checked against those
    of its robot's source when they are known."""
    graph = _Graph(robots, edges, temporal)
    by_key = {robot.key: robot for robot in robots}
    trails: list[TrailPlan] = []
    taken: dict[str, int] = {}
    for index, spec in enumerate(ctx.data.get("trails", [])):
        trail = _trail(ctx, index, spec, by_key, graph, root, timelines)
        if trail is None:
            continue
        if trail.entity in taken:
            ctx.problems.add(
                f"trails[{taken[trail.entity]}] already draws {trail.robot}'s {quoted(trail.link)}; one trail per link of a robot",
                ctx.where("trails", index, "link"),
            )
            continue
        taken[trail.entity] = index
        trails.append(trail)
    return tuple(trails)


def _trail(
    ctx: CompileContext,
    index: int,
    spec: dict[str, Any],
    robots: dict[str, RobotPlan],
    graph: _Graph,
    root: str,
    timelines: Mapping[str, tuple[tuple[str, str], ...]],
) -> TrailPlan | None:
    where = ctx.where("trails", index)
    robot = _robot(ctx, index, spec, robots)
    if robot is None:
        return None
    link = spec["link"]
    if link not in robot.links:
        ctx.problems.add(
            f"robot '{robot.key}' has no link {quoted(link)}{did_you_mean(link, robot.links)}", ctx.where("trails", index, "link")
        )
        return None
    frame = spec.get("frame", root)
    frame_where = ctx.where("trails", index, "frame") if "frame" in spec else where
    if frame not in graph.frames:
        ctx.problems.add(f"no frame {quoted(frame)} in the frame graph{did_you_mean(frame, graph.frames)}", frame_where)
        return None
    path = _path(ctx, graph, robot, link, frame, frame_where)
    source = robot.source or ""
    window = _window(ctx, index, spec, source, timelines.get(source, ()))
    if path is None or window is None:
        return None
    start_link, chain = path
    color = spec.get("color")
    rgba = None if color is None else (*color, 255)[:4]
    return TrailPlan(
        robot=robot.key,
        link=link,
        frame=frame,
        start_link=start_link,
        edges=chain,
        entity=f"{robot.entity_path_prefix}/{TRAILS_FOLDER}/{link}",
        style=spec.get("style", "line"),
        color=rgba,
        window=window[0],
        window_unit=window[1],
        timelines=window[2],
        where=where,
    )


def _robot(ctx: CompileContext, index: int, spec: dict[str, Any], robots: dict[str, RobotPlan]) -> RobotPlan | None:
    """The trail's robot: `robot:`, or the config's only robot; a robot no source drives has no path to draw."""
    keys = list(ctx.data["robots"])
    key = spec.get("robot")
    if key is None and len(keys) > 1:
        ctx.problems.add(
            f"trails[{index}] needs robot: one of {listing(keys)} (the config has {len(keys)} robots)", ctx.where("trails", index)
        )
        return None
    key = key if key is not None else keys[0]
    if key not in ctx.data["robots"]:
        ctx.problems.add(f"no robot {quoted(key)}{did_you_mean(key, keys)} (robots: {listing(keys)})", ctx.where("trails", index, "robot"))
        return None
    robot = robots.get(key)  # None: the robot did not compile, reported there
    if robot is not None and robot.source is None:
        ctx.problems.add(f"robot '{key}' is driven by no source: its links do not move, so they leave no trail", ctx.where("trails", index))
        return None
    return robot


def _path(
    ctx: CompileContext, graph: _Graph, robot: RobotPlan, link: str, frame: str, where: Where
) -> tuple[str, tuple[EdgePlan, ...]] | None:
    """(the URDF link the joint chain starts from, the static edges above it, top down), walking up from the link."""
    prefixed = robot.frame_prefix + link
    walked = [prefixed]
    current = prefixed
    while current != frame and current in graph.joint_parent and graph.joint_parent[current][0] is robot:
        if current in graph.temporal:  # a floating joint's child placed by a temporal edge
            _through_temporal(ctx, graph.temporal[current], link, frame, where)
            return None
        current = robot.frame_prefix + graph.joint_parent[current][1]
        walked.append(current)
    if current == frame:
        return current[len(robot.frame_prefix) :], ()
    start = current[len(robot.frame_prefix) :]
    chain: list[EdgePlan] = []
    while current != frame:
        if current in graph.temporal:
            _through_temporal(ctx, graph.temporal[current], link, frame, where)
            return None
        edge = graph.static.get(current)
        if edge is None and current in graph.joint_parent:  # mounted on another robot's link: its joints move it
            other = graph.joint_parent[current][0].key
            ctx.problems.add(
                f"link {quoted(link)} of robot '{robot.key}' hangs from link {quoted(current)} of robot '{other}', which that "
                f"robot's joints move: a trail follows one robot's joints; choose {quoted(current)} or a frame below it",
                where,
            )
            return None
        if edge is None:
            ctx.problems.add(
                f"frame {quoted(frame)} is not above link {quoted(link)} of robot '{robot.key}': the frames above it are "
                f"{listing(walked[1:], limit=8, separator=' -> ', empty='none')}; choose one of them",
                where,
            )
            return None
        chain.append(edge)
        current = edge.parent
        walked.append(current)
    return start, tuple(reversed(chain))


def _through_temporal(ctx: CompileContext, edge: TemporalEdgePlan, link: str, frame: str, where: Where) -> None:
    ctx.problems.add(
        f"frame {quoted(frame)} reaches link {quoted(link)} only through the temporal edge {edge.parent} -> {edge.child} "
        f"({edge.label}, source '{edge.source}'), which the robot's joint values do not give; choose a frame below it, "
        f"e.g. {quoted(edge.child)}",
        where,
    )


def _window(
    ctx: CompileContext, index: int, spec: dict[str, Any], source: str, timelines: tuple[tuple[str, str], ...]
) -> tuple[float | None, WindowUnit, tuple[str, ...]] | None:
    """(span, unit, the timelines it applies to); a window that is neither a duration nor a row count, or whose unit
    fits none of the source's timelines, is a problem."""
    if "window" not in spec:
        return None, "s", tuple(name for name, _ in timelines)
    where = ctx.where("trails", index, "window")
    parsed = parse_window(str(spec["window"]))
    if parsed is None:
        ctx.problems.add(
            f"window {quoted(str(spec['window']))} is not a duration (e.g. 2 s, 500 ms, 1 min) nor a number of rows (e.g. 200 rows)", where
        )
        return None
    span, unit = parsed
    beyond = window_beyond(span, unit)
    if beyond is not None:
        ctx.problems.add(f"window {quoted(str(spec['window']))} is {beyond}", where)
        return None
    if not timelines:
        return span, unit, ()
    fitting = tuple(name for name, kind in timelines if (kind == "sequence") == (unit == "rows"))
    if not fitting:
        name, kind = timelines[0]
        wanted = "a number of rows (e.g. 200 rows)" if kind == "sequence" else "a duration (e.g. 2 s)"
        ctx.problems.add(f"source '{source}' gives its rows on the {kind} timeline {quoted(name)}: give the window as {wanted}", where)
        return None
    return span, unit, fitting

"""`urdf-pipeline snapshot`: pictures of a written recording at chosen times on its timeline.

Each picture is framed on the pose it shows, so a robot that sweeps a metre over a segment still fills its pictures.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import UserError, Where, did_you_mean, listing, shown
from ..plan import Plan, RobotPlan
from .camera import framing
from .captions import band_height, burn_caption
from .frames import RecordedTransforms, Timeline, read_transforms, transform_timelines
from .headless_viewer import HeadlessViewer, Shot, Size, write_png
from .mesh_bounds import GeometryBoxes, geometry_boxes
from .plan_pictures import DEFAULT_SIZE, Picture, extent, require_picture_path, robot_frames, view_contents

if TYPE_CHECKING:
    from rerun.chunk import Chunk

SCENE = "scene"
KEYWORDS = ("first", "middle", "last")


@dataclass(frozen=True)
class SnapshotRequest:
    segment: str | None = None  # default: the first segment
    at: str | None = None  # "T,..." on the segment's timeline; default first, middle, last
    view: str = SCENE  # "scene" or a robot key
    size: Size = DEFAULT_SIZE
    folder: Path | None = None  # default: `pictures/` beside the segment's recording


def snapshot(plan: Plan, request: SnapshotRequest) -> tuple[Picture, ...]:
    segment = plan.segment_named(request.segment, "--segment", first_by_default=True)
    robots = plan.robots if request.view == SCENE else tuple(r for r in plan.robots if r.key == request.view)
    if not robots:
        keys = [r.key for r in plan.robots]
        raise UserError(
            f"--view {shown(request.view)}: no such robot (robots: {listing(keys)}; or 'scene'){did_you_mean(request.view, keys)}"
        )
    chunks = _recording(plan, segment.output)
    timelines = transform_timelines(chunks, [robot.fk_entity for robot in robots])
    timeline = timelines[0] if timelines else None
    transforms = read_transforms(chunks, timeline)
    times = picture_times(request.at, timeline, transforms.times)
    whole = request.view == SCENE
    if not np.isfinite(transforms.positions(plan.root_frame, robot_frames(robots))).all(axis=2).any():
        raise UserError(f"{segment.output}: no link of {request.view} reaches the root frame {plan.root_frame} in the recording")
    size = request.size
    band = band_height(size, 2)
    boxes = geometry_boxes(chunks)
    folder = request.folder if request.folder is not None else segment.output.parent / "pictures"
    shots = [(time, folder / f"{segment.id}.{request.view}.{_time_label(timeline, time)}.png") for time in times]
    for _, path in shots:
        require_picture_path(path)
    pictures = []
    title = shown(plan.config_path.name) + ("" if whole else f" · robot {shown(request.view)}")
    with HeadlessViewer(size) as viewer:
        store = viewer.show(plan.application_id, segment.id, chunks)
        for time, path in shots:
            points, radii = _framed_at(transforms, boxes, plan, robots, whole, time)
            camera = framing(points, size.width, size.height, band, radii)
            png = viewer.draw(store, Shot(camera, view_contents(robots, whole), timeline, time))
            write_png(path, burn_caption(png, [title, f"segment {shown(segment.id)} · {time_caption(timeline, time)}"], band))
            pictures.append(Picture(_time_label(timeline, time).replace("-", " ", 1), path))
    return tuple(pictures)


def _recording(plan: Plan, output: Path) -> list[Chunk]:
    """The segment's chunks; the split layout's model (meshes, static joints) first, as `run --spawn` sends it."""
    from rerun.chunk import RrdReader

    files = ([plan.dataset.model] if plan.dataset.layout == "split" and plan.dataset.model is not None else []) + [output]
    for file in files:
        if not file.is_file():
            raise UserError(f"no recording at {file}: write it first (urdf-pipeline run {plan.config_path})", Where(plan.config_path, 0))
    return [chunk for file in files for chunk in RrdReader(file).stream().to_chunks()]


def _framed_at(
    transforms: RecordedTransforms, boxes: GeometryBoxes, plan: Plan, robots: Sequence[RobotPlan], whole: bool, time: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """What the picture at `time` frames: the pose it shows (so it fills the picture), or, should no link be placed yet
    at that time (or the recording not move), the robots over the whole segment."""
    if time is not None:
        points, radii = extent(transforms, boxes, plan.root_frame, robots, whole, np.array([time], dtype=np.int64))
        if np.isfinite(points).all(axis=1).any():
            return points, radii
    return extent(transforms, boxes, plan.root_frame, robots, whole)


def time_caption(timeline: Timeline | None, value: int | None) -> str:
    """The time on its timeline, as a caption says it: `frame_index 450`, `time 1.500 s`, `ts 2024-01-01T12:00:00.000Z`."""
    if timeline is None or value is None:
        return "static: the recording has no temporal transform"
    unit = " s" if timeline.kind == "duration" else ""
    return f"{shown(timeline.name)} {_shown(timeline, value)}{unit}"


def picture_times(text: str | None, timeline: Timeline | None, times: np.ndarray) -> list[int | None]:
    """The times to draw, on the recording's timeline: `first`, `middle`, `last` or values (a sequence number;
    seconds for a duration timeline; seconds since the epoch or an ISO 8601 date and time for a timestamp one)."""
    if timeline is None or not len(times):
        if text:
            raise UserError("--at: the recording has no temporal transform (nothing moves): leave --at out for its one picture")
        return [None]
    tokens = [token.strip() for token in (text or ",".join(KEYWORDS)).split(",") if token.strip()]
    if not tokens:
        raise UserError("--at: give one or more times, comma-separated (e.g. first,last or 0,450)")
    chosen: list[int | None] = []
    for token in tokens:
        keyword = {"first": 0, "middle": (len(times) - 1) // 2, "last": len(times) - 1}.get(token)
        value = int(times[keyword]) if keyword is not None else _value(token, timeline)
        if not times[0] <= value <= times[-1]:
            shown = f"{_shown(timeline, int(times[0]))} .. {_shown(timeline, int(times[-1]))}"
            raise UserError(f"--at {token}: outside the segment's {timeline.name} range {shown}")
        if value not in chosen:
            chosen.append(value)
    return chosen


def _value(token: str, timeline: Timeline) -> int:
    try:
        if timeline.kind == "sequence":
            return int(token)
        if timeline.kind == "timestamp" and not _is_number(token):
            return int(np.datetime64(token.rstrip("Z"), "ns").astype(np.int64))
        return round(float(token) * 1e9)
    except ValueError:
        unit = {"sequence": "an integer", "duration": "seconds", "timestamp": "seconds since the epoch or an ISO 8601 time"}
        raise UserError(f"--at {token}: not {unit[timeline.kind]} on the {timeline.kind} timeline {timeline.name}") from None


def _is_number(token: str) -> bool:
    try:
        float(token)
        return True
    except ValueError:
        return False


def _shown(timeline: Timeline, value: int) -> str:
    if timeline.kind == "sequence":
        return str(value)
    if timeline.kind == "duration":
        return f"{value / 1e9:.3f}"
    return str(np.datetime64(value, "ns").astype("datetime64[ms]")) + "Z"


def _time_label(timeline: Timeline | None, value: int | None) -> str:
    """For file names: `frame_index-450`, `time-1.500s`, `timestamp-2024-01-01T12-00-00.000Z`."""
    if timeline is None or value is None:
        return "static"
    shown = _shown(timeline, value).replace(":", "-")
    return f"{timeline.name}-{shown}{'s' if timeline.kind == 'duration' else ''}"

"""The Python API: what the command line does, as typed calls for notebooks and users' own scripts.

Each call raises `ConfigError` (the command line's one error family, `urdf_pipeline.errors.UserError`) with the same
located messages the CLI prints (`error.lines()`), and prints nothing but Rerun's and the run's progress lines on
stderr, as `run` does.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import UserError, UserErrors
from ..plan import Plan

if TYPE_CHECKING:
    from rerun import RecordingStream

    from ..execute import RobotKinematics
    from ..live_views import LiveView, TimeKind

ConfigError = UserError


def load(path: str | os.PathLike[str], *, episodes: str | Iterable[int] | None = None) -> Plan:
    """Compile and validate a config, as `urdf-pipeline validate` does, into the frozen `Plan` a run executes.
    `episodes` selects segments as `run --episodes` does (`"all"`, `"10:20"`, or episode numbers)."""
    from ..compile import compile_config

    return compile_config(Path(path), _episodes(episodes))


def run(
    path: str | os.PathLike[str], *, episodes: str | Iterable[int] | None = None, jobs: int | None = None, force: bool = False
) -> list[Path]:
    """Do what `urdf-pipeline run` does: write every segment's recording (the model, in the split layout) that is not
    up to date, in `jobs` processes (default: the CPUs this process may use), and return the paths of the recordings, written or already
    up to date. A segment that fails raises ConfigError (with every failed segment's lines) after the others are done."""
    from ..dataset import RunOptions, run_dataset, usable_cpus

    plan = load(path, episodes=episodes)
    finished = run_dataset(plan, RunOptions(jobs or usable_cpus(), "local", None, force))
    if finished.interrupted:
        raise KeyboardInterrupt
    if finished.bugs:
        bug = finished.bugs[0]
        raise RuntimeError(f"urdf-pipeline: internal error in {bug.label} (a bug, not your config):\n{bug.reason}")
    if finished.failed:
        lines = [(r.label, line.removeprefix("error: ")) for r in finished.failed for line in r.reason.splitlines()]
        raise UserErrors([UserError(f"{label}: {line}") for label, line in lines])
    return list(finished.outputs)


def log(path: str | os.PathLike[str] | Plan, recording: RecordingStream | None = None, *, segment: str | None = None) -> dict[str, int]:
    """Log one segment's robot model, forward kinematics and calibration edges into `recording` (default: Rerun's
    current one), next to the caller's own cameras and point clouds, streamed as a run writes (bounded memory).
    `segment`: a segment id; may be left out when the config has one segment. Returns the rows read per robot.
    The checks a run makes after reading (limits, NaN, zero rows) raise ConfigError once the data is sent."""
    import rerun as rr

    from ..execute import log_segment

    plan = path if isinstance(path, Plan) else load(path)
    target = recording if recording is not None else rr.get_global_data_recording()
    if target is None:
        raise UserError("urdf_pipeline.log: no recording given and no current Rerun recording (call rr.init first)")
    return log_segment(plan.for_segment(plan.segment_named(segment, "segment=", first_by_default=False)), target)


def forward_kinematics(plan: Plan | str | os.PathLike[str], segment: str | None = None) -> dict[str, RobotKinematics]:
    """Every link's pose in its robot's root frame at every row of a segment, per robot key: `translations` (links x
    rows x 3), `quaternions` (x, y, z, w), `matrices()` (links x rows x 4 x 4), `times` per timeline. The same values,
    corrections and checks as a run; float64. Memory grows with the segment (56 bytes per link and row)."""
    from ..execute import segment_kinematics

    compiled = plan if isinstance(plan, Plan) else load(plan)
    return segment_kinematics(compiled.for_segment(compiled.segment_named(segment, "segment=", first_by_default=False)))


def live(
    path: str | os.PathLike[str],
    recording: RecordingStream | None = None,
    *,
    robot: str | None = None,
    spawn: bool | None = None,
    connect: str | None = None,
    save: str | os.PathLike[str] | None = None,
    timeline: str | None = None,
    time_kind: TimeKind = "timestamp",
    max_delay: float = 0.01,
) -> LiveView:
    """A live view of one robot of a config, for a control loop: `view.push(values, time=None)` one sample (a sequence
    in the source's `names` order, or a mapping name -> value), `view.push_batch(rows, times)`, `view.close()` (or
    `with`). It logs the robot's model and the calibration edges once, then each sample's joint transforms and temporal
    edges, with the config's mapping, units, mimic joints, holds and limits (values beyond them are reported every few
    seconds and clamped or shown as `on_violation` says). Source names come from `names:`, else from the source's data.

    `recording`: yours; else a new one that `spawn`s a viewer (default: when neither `connect` nor `save` is given;
    no screen here: ConfigError at once, as `live --spawn` says), `connect`s to one ("rerun+http://HOST:PORT/proxy")
    and/or `save`s to a file, closed with the view. `timeline` (default: the source's, "time" for a file source) holds
    `time_kind` values: seconds since the epoch (timestamp, default: now), seconds (duration, default: since the view
    began) or integers (sequence, default: a counter). Pushed samples are sent together every `max_delay` seconds by a
    thread of the view's (0: each push is sent at once)."""
    from ..compile import FROM_LIVE_DATA, check_config
    from ..live_views import LiveView, live_recording
    from ..process import spawn_viewer

    plan = check_config(Path(path), FROM_LIVE_DATA).checked()
    chosen = plan.robot_named(robot)
    if recording is not None and (spawn or connect or save):
        raise UserError("urdf_pipeline.live: give either a recording or spawn/connect/save for one it makes, not both")
    if recording is None and spawn is False and connect is None and save is None:
        raise UserError("urdf_pipeline.live: spawn=False leaves the view nowhere to send to: give connect, save or a recording")
    spawned = spawn_viewer() if recording is None and (spawn or (spawn is None and connect is None and save is None)) else None
    target = recording if recording is not None else live_recording(plan.application_id, save, spawned, connect)
    return LiveView(plan, chosen, target, timeline=timeline, time_kind=time_kind, max_delay=max_delay, owns_recording=recording is None)


def _episodes(episodes: str | Iterable[int] | None) -> str | None:
    if episodes is None or isinstance(episodes, str):
        return episodes
    return ",".join(str(int(e)) for e in episodes)

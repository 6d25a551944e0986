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
    up to date, in `jobs` processes (default: every core), and return the paths of the recordings, written or already
    up to date. A segment that fails raises ConfigError (with every failed segment's lines) after the others are done."""
    from ..dataset import RunOptions, run_dataset

    plan = load(path, episodes=episodes)
    finished = run_dataset(plan, RunOptions(jobs or os.cpu_count() or 1, "local", None, force))
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


def _episodes(episodes: str | Iterable[int] | None) -> str | None:
    if episodes is None or isinstance(episodes, str):
        return episodes
    return ",".join(str(int(e)) for e in episodes)

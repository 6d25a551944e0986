"""One robot of a config, live: its model once, then each sample's joint transforms and temporal edges, sent into a
Rerun recording as they come, with the run's corrections (map, units, sign, offset, wrap, holds, mimic joints, limits,
NaN policy) and the run's FK (`execute`'s closed-form joint transforms, checked against Rerun's at construction).

A batch costs one `send_columns` per entity, whatever its rows, so `push` checks the sample and keeps it, and the
view's own flusher thread sends what is kept every `max_delay` (10 ms: within a 60 Hz viewer's frame).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import pyarrow as pa

from ..errors import Problems, Where, warn
from ..execute import (
    ClosedFormJointTransforms,
    TemporalEdgeStats,
    TemporalEdgeValues,
    cached_tree,
    calibration_stream,
    check_joint_statistics,
    check_temporal_edges,
    provenance_stream,
    robot_model_stream,
    transform_fields,
)
from ..plan import LivePlan, RobotPlan
from ..sources import ChannelStats, JointValueMapper, RobotStats
from .value_rows import ValueRows

if TYPE_CHECKING:
    from rerun import RecordingStream

TimeKind = Literal["timestamp", "duration", "sequence"]
Values = Sequence[float] | Mapping[str, float] | np.ndarray


class LiveView:
    """One robot's live view: `urdf_pipeline.live` (api/calls.py) says what `push` and `push_batch` take."""

    def __init__(
        self,
        plan: LivePlan,
        robot: RobotPlan,
        recording: RecordingStream,
        *,
        timeline: str | None = None,
        time_kind: TimeKind = "timestamp",
        scene: bool = True,
        max_delay: float = 0.01,
        owns_recording: bool = False,
    ) -> None:
        assert robot.source is not None, "a live view drives a robot that has a source"
        self.plan, self.robot, self.recording = plan, robot, recording
        self.source = plan.source_named(robot.source)
        self.timeline = timeline or self.source.timeline
        self.time_kind: TimeKind = time_kind
        self.mapper = JointValueMapper(robot, self.source)
        tree = cached_tree(robot)
        self.fk = ClosedFormJointTransforms(tree, list(self.mapper.joint_names))
        self.temporal = [TemporalEdgeValues(e, self.source) for e in plan.temporal_edges if e.source == self.source.name]
        read = [self.mapper.columns, *(v.columns for v in self.temporal)]
        self.rows = ValueRows(self.source, np.unique(np.concatenate(read)), f"urdf_pipeline.live robot '{robot.key}'")
        self.reports = LimitReports(self.mapper, self.temporal)
        self.started = time.monotonic_ns()
        self.count = 0  # samples pushed
        self.sent = 0  # samples sent (a sample left out for NaN values is pushed, not sent)
        self.max_delay = max_delay
        self.owns_recording = owns_recording  # made by urdf_pipeline.live: flushed and disconnected by close()
        self._pending: list[np.ndarray] = []  # rows pushed and not yet sent, and their times
        self._pending_times: list[int] = []
        self._lock = threading.Lock()  # the pending rows and the count: held for microseconds
        self._sending = threading.Lock()  # one send at a time, in push order (the mapper carries hold_last's state)
        self._failure: BaseException | None = None  # the flusher thread's, raised in the caller's next call
        self._stop = threading.Event()
        self._flusher: threading.Thread | None = None
        if owns_recording:  # what it was made from, as a run's recordings say it (`live --save` may replace it later)
            recording.send_chunks(provenance_stream(plan, "all", {"live_from": "urdf_pipeline.live"}))
        recording.send_chunks(robot_model_stream(robot, tree))
        if scene:  # the calibration edges and the robots no source drives (a table, a camera mount)
            recording.send_chunks(calibration_stream(plan.edges))
            for other in plan.robots:
                if other.source is None:
                    recording.send_chunks(robot_model_stream(other, cached_tree(other)))

    def push(self, values: Values, time: float | None = None) -> None:
        """One sample: checked now (a wrong count or name raises here), sent within `max_delay`."""
        row = self.rows.many([values])[0]
        stamp = self._stamp(time)
        self._raise_failure()
        with self._lock:
            self.count += 1
            self._pending.append(row)
            self._pending_times.append(stamp)
            full = len(self._pending) >= _MAX_PENDING or self.max_delay <= 0
        if full:
            self.flush()
        elif self._flusher is None:
            self._start_flusher()

    def push_batch(self, values: Sequence[Values] | np.ndarray, times: Sequence[float] | np.ndarray | None = None) -> None:
        """Rows of samples, `times` one per row (None: as `push` stamps them), sent at once (after earlier pushes)."""
        raw = self.rows.many(values)
        stamps = self._times(len(raw), times)
        self._raise_failure()
        self._send_now(raw, stamps)

    def push_named(self, names: Sequence[tuple[str, ...]], values: Sequence[np.ndarray], times_ns: np.ndarray) -> None:
        """Rows that name their values (JointState messages), stamped in int64 nanoseconds on the view's timeline,
        sent at once."""
        self._send_now(self.rows.named(names, values), np.asarray(times_ns, dtype=np.int64))

    def flush(self) -> None:
        """Send what `push` kept now."""
        self._raise_failure()
        with self._sending:
            self._send(*self._take())

    def close(self) -> None:
        """Send what is kept, stop the flusher, report what the last window found. The recording is the caller's
        to flush (or the owner's: `urdf_pipeline.live` closes the one it made)."""
        self._stop.set()
        if self._flusher is not None:
            self._flusher.join()
        self.flush()
        with self._sending:
            self.reports.report(final=True)
        if self.owns_recording:
            self.recording.flush()
            self.recording.disconnect()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _send_now(self, raw: np.ndarray, stamps: np.ndarray) -> None:
        """Rows sent at once, after what earlier pushes kept."""
        with self._sending:
            self._send(*self._take())
            with self._lock:
                self.count += len(raw)
            self._send(raw, stamps)

    def _take(self) -> tuple[np.ndarray, np.ndarray]:
        """The pending rows and their times, taken under the short lock (pushes wait only for this)."""
        with self._lock:
            rows, stamps = self._pending, self._pending_times
            self._pending, self._pending_times = [], []
        if not rows:
            return np.empty((0, self.rows.width)), np.empty(0, dtype=np.int64)
        return np.vstack(rows), np.array(stamps, dtype=np.int64)

    def _start_flusher(self) -> None:
        with self._lock:
            if self._flusher is not None:
                return
            self._flusher = threading.Thread(target=self._flush_every, name="urdf-pipeline-live-flush", daemon=True)
        self._flusher.start()

    def _flush_every(self) -> None:
        """What was pushed is sent every `max_delay`, so pushes cost the caller microseconds, and pushes that stop
        coming are still sent."""
        while not self._stop.wait(self.max_delay):
            try:
                with self._sending:
                    self._send(*self._take())
            except BaseException as exc:  # given to the caller's next call, never lost
                self._failure = exc
                return

    def _raise_failure(self) -> None:
        if self._failure is not None:
            failure, self._failure = self._failure, None
            raise failure

    def _stamp(self, given: float | None) -> int:
        """One sample's time as `_times` gives it, without numpy (a push is a few microseconds)."""
        if given is not None:
            return int(given) if self.time_kind == "sequence" else round(float(given) * 1e9)
        if self.time_kind == "sequence":
            return self.count
        return time.time_ns() if self.time_kind == "timestamp" else time.monotonic_ns() - self.started

    def _times(self, rows: int, given: Sequence[float] | np.ndarray | None) -> np.ndarray:
        """int64: nanoseconds (timestamp, duration) or the sequence's values."""
        if given is not None:
            times = np.asarray(given)
            if times.shape != (rows,):
                raise ValueError(f"{times.size} times for {rows} samples: give one time per sample")
            if self.time_kind == "sequence":
                return times.astype(np.int64)
            return np.round(times.astype(np.float64) * 1e9).astype(np.int64)
        if self.time_kind == "sequence":
            return np.arange(self.count, self.count + rows, dtype=np.int64)
        return np.full(rows, self._stamp(None), dtype=np.int64)

    def _send(self, raw: np.ndarray, times: np.ndarray) -> None:
        if not len(raw):
            return
        values, left_out = self.mapper.urdf_values(raw)
        keep = np.ones(len(raw), dtype=bool) if left_out is None else ~left_out
        if self.robot.nan_policy == "error":  # counted by the mapper, reported by the window; never drawn
            keep &= np.isfinite(values).all(axis=1)
        if keep.any():
            kept = keep if not keep.all() else slice(None)
            self._send_joints(values[kept], times[kept])
        for edge in self.temporal:
            self._send_edge(edge, raw, times)
        self.sent += int(keep.sum())
        if self.reports.due():
            self.reports.report()

    def _send_joints(self, values: np.ndarray, times: np.ndarray) -> None:
        """The run's FK batches (one list of joint transforms per row, float32 as a run writes them), scattered to
        one Transform3D row per joint as the run's scatter lens does."""
        self._send_transforms(self.robot.fk_entity, self.fk(values).values, np.repeat(times, len(self.fk.names)))

    def _send_edge(self, edge: TemporalEdgeValues, raw: np.ndarray, times: np.ndarray) -> None:
        """A temporal edge's rows through the run's own function (its checks and statistics); rows it cannot place
        (NaN, a zero quaternion) are counted for the window's report and left out."""
        batch, usable = edge.placed(pa.FixedSizeListArray.from_arrays(pa.array(raw.reshape(-1)), raw.shape[1]))
        structs = batch.values
        if usable.all():
            self._send_transforms(edge.edge.entity, structs, times)
        elif usable.any():
            self._send_transforms(edge.edge.entity, structs.filter(pa.array(usable)), times[usable])

    def _send_transforms(self, entity: str, structs: pa.StructArray, times: np.ndarray) -> None:
        """{translation, quaternion, parent_frame, child_frame} structs, one Transform3D row each, in one call."""
        import rerun as rr

        columns = [rr.ComponentColumn(descriptor, _Arrow(structs.field(name))) for name, descriptor in transform_fields()]
        self.recording.send_columns(entity, indexes=[self._time_column(times)], columns=columns)

    def _time_column(self, times: np.ndarray) -> Any:
        import rerun as rr

        if self.time_kind == "sequence":
            return rr.TimeColumn(self.timeline, sequence=times)
        if self.time_kind == "duration":
            return rr.TimeColumn(self.timeline, duration=times.astype("timedelta64[ns]"))
        return rr.TimeColumn(self.timeline, timestamp=times.astype("datetime64[ns]"))


_MAX_PENDING = 1000  # rows kept at most: a loop faster than 100 kHz sends every 1000 pushes
REPORT_SECONDS = 5.0  # a live view's limit reports: at most one per window this long


class _Arrow:
    """An arrow array already of a component's type (the run's FK batches are built in Rerun's own types)."""

    def __init__(self, array: pa.Array) -> None:
        self.array = array

    def as_arrow_array(self) -> pa.Array:
        return self.array


class LimitReports:
    """The window's statistics of one live view's mapper and temporal edges (limits, NaN, dropped rows, as a run reports
    them after its pass), reported when something is wrong and the last report is REPORT_SECONDS old (the first at
    once), then started afresh. A stream cannot be refused: values beyond the limits are clamped or shown as given
    (`joints.limits.on_violation`: clamp clamps; error and ignore show them, error as an error-worded warning naming
    the likely cause), and a sample with NaN values is left out unless `joints.nan` says how to fill it."""

    def __init__(self, mapper: JointValueMapper, temporal: list[TemporalEdgeValues]) -> None:
        self.mapper, self.temporal = mapper, temporal
        self.last = -float("inf")
        self.before = 0  # samples of the windows already reported: row numbers in messages count from the view's start

    def due(self) -> bool:
        return time.monotonic() - self.last >= REPORT_SECONDS and self._anything()

    def report(self, final: bool = False) -> None:
        """The window's warnings (`final`: whatever is left when the view closes), then a fresh window."""
        if not (self._anything() and (final or self.due())):
            return
        for channel in self.mapper.stats.channels:
            if channel.first_nonfinite_row >= 0:
                channel.first_nonfinite_row += self.before
        problems = Problems()
        lines: list[tuple[str, Where | None]] = [(text, None) for text in check_joint_statistics(self.mapper, problems)]
        check_temporal_edges([v for v in self.temporal if v.stats.rows], problems)
        lines += [(error.message, error.where) for error in problems.errors]
        window = "since the view started" if self.last == -float("inf") else f"in the last {time.monotonic() - self.last:.0f} s"
        for text, where in lines:
            warn(f"live: {text} ({window}; a live view shows the samples it can, it cannot refuse them)", where)
        self.last = time.monotonic()
        self.before += self.mapper.stats.rows
        self.mapper.stats = RobotStats(channels=[ChannelStats() for _ in self.mapper.robot.channels])
        for values in self.temporal:
            values.stats = TemporalEdgeStats()

    def _anything(self) -> bool:
        stats = self.mapper.stats
        if stats.dropped_rows or stats.filled_rows:
            return True
        if any(c.clamped_rows or c.beyond_rows or c.nonfinite_rows for c in stats.channels):
            return True
        return any(v.stats.nonfinite_rows or v.stats.zero_quaternion_rows for v in self.temporal)

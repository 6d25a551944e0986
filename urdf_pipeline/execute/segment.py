"""Run a plan: build the lazy streams, write them as they are read (bounded memory), then check what the pass found
before the file is renamed into place."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from ..errors import Problems
from ..logs import note as log_note
from ..logs import say
from ..plan import RecordingPlan, RobotPlan
from ..sources import CallbackErrors, JointValueMapper, module_for, with_sorting_retry
from .differences import PairDifferences, pair_differences
from .edges_stream import calibration_stream
from .fk_stream import JointTransformBatches, fk_stream
from .joint_series import series_names_stream
from .limits_report import check_joint_statistics
from .manifest_entry import SegmentSummary
from .model_stream import cached_tree, robot_model_stream
from .progress_meter import RowMeter, source_meter
from .provenance import provenance_stream
from .ranges_and_preview import TimeRanges, ValuePreview, observed, segment_summary
from .remote_inputs import local_inputs
from .stream_writer import drain_streams
from .temporal_stream import EdgeRows, check_temporal_edges, temporal_edge_streams
from .tf_stream import bag_edge_streams
from .trail_stream import TrailPositions, trail_statics_stream
from .writer import write_file_atomically

if TYPE_CHECKING:
    from rerun import RecordingStream
    from rerun.chunk import LazyChunkStream

Parts = Literal["all", "layer", "model"]  # single layout | split layout's per-segment layer | split layout's model asset


@dataclass(frozen=True)
class RunResult:
    output: Path
    rows: dict[str, int]  # robot key -> rows of joint values
    notes: tuple[str, ...]
    seconds: float
    summary: SegmentSummary | None = None  # what the manifest lists of it (None for the split layout's model)


def execute(
    plan: RecordingPlan,
    parts: Parts = "all",
    provenance: dict[str, str] | None = None,
    on_note: Callable[[str], None] = log_note,
    quiet: bool = False,
    rows_expected: int | None = None,
) -> RunResult:
    """Write one recording. `provenance` adds fields (the content hash) to the recording's properties; `on_note` and
    `quiet` (no progress lines) let a worker running many segments keep its output for the run's summary;
    `rows_expected` (from the source's metadata) gives the progress lines a share done and an ETA."""
    log: Callable[[str], None] = (lambda _: None) if quiet else say  # one segment among many: the run's progress bar speaks
    started = time.perf_counter()
    # what it does, never "writing": a segment its checks refuse (after the pass) writes nothing, and says so
    if parts == "model":
        log(f"building the model of {len(plan.robots)} robot(s)")
    else:
        log(f"reading {len(plan.sources)} source(s), computing forward kinematics for {len(plan.robots)} robot(s)")
    # A source found out of time order part-way is read again, whole and sorted: the attempt opens every stream anew.
    with local_inputs(plan) as local:  # remote sources fetched into this machine's cache, held while read
        written, rows, notes, summary = with_sorting_retry(lambda: _write(local, parts, provenance or {}, on_note, quiet, rows_expected))
    return RunResult(written, rows, notes, time.perf_counter() - started, summary)


@dataclass
class _Pass:
    """One read of a segment's sources: the streams, and what the checks after the pass need."""

    streams: list[LazyChunkStream]
    errors: CallbackErrors
    mappers: list[JointValueMapper]
    temporal_values: Sequence[EdgeRows]
    meters: list[RowMeter]  # one per source read, cleared when the pass ends (a terminal's redrawn line)
    times: TimeRanges  # the summary's time ranges and value previews, gathered as the values pass
    previews: list[ValuePreview]
    pairs: tuple[PairDifferences, ...] = ()  # compare: each copy against its measured robot

    def drain(self, sink: Callable[[LazyChunkStream], None]) -> None:
        """The streams into `sink`; the meters are finished however the pass ends (written, failed, interrupted)."""
        try:
            drain_streams(self.streams, sink, self.errors)
        finally:
            for meter in self.meters:
                meter.finish()

    def check(self, on_note: Callable[[str], None]) -> tuple[str, ...]:
        """After the pass: limits, NaN, zero rows, temporal edges. Notes go to `on_note`; problems raise, all at once."""
        problems = Problems()
        notes = tuple(note for mapper in self.mappers for note in check_joint_statistics(mapper, problems))
        check_temporal_edges(self.temporal_values, problems)
        for note in notes:
            on_note(note)
        problems.raise_if_any()
        return notes

    def rows(self) -> dict[str, int]:
        return {m.robot.key: m.stats.rows for m in self.mappers}


def _open(plan: RecordingPlan, parts: Parts, provenance: dict[str, str] | None, quiet: bool, rows_expected: int | None) -> _Pass:
    """Every stream of one attempt, opened anew (a retry after a source was found out of order reads it again).
    `provenance` None: no properties entity (a user's own recording, see `log_segment`)."""
    errors = CallbackErrors()
    mappers: list[JointValueMapper] = []
    meters: list[RowMeter] = []
    times = TimeRanges()
    previews: list[ValuePreview] = []
    pairs = tuple(pair_differences(plan)) if parts != "model" else ()
    streams = []
    trees = {robot.key: cached_tree(robot) for robot in plan.robots}
    if parts != "layer":
        for robot in plan.robots:
            streams.append(robot_model_stream(robot, trees[robot.key]))
    if parts != "model":
        for source in plan.sources:
            driven: list[tuple[RobotPlan, JointTransformBatches]] = []
            meter = None if quiet else source_meter(plan, source, rows_expected)  # its rows counted once, by the first robot
            meters += [meter] if meter is not None else []
            for robot in plan.robots_for(source.name):
                mapper = JointValueMapper(robot, source)
                mappers.append(mapper)
                previews.append(ValuePreview(robot.key, robot.channels, tuple(p for p in pairs if robot.key in (p.copy, p.measured))))
                series = plan.output.joint_series and bool(robot.channels)
                trails = [TrailPositions(t, trees[robot.key], list(mapper.joint_names)) for t in plan.output.trails if t.robot == robot.key]
                batches = JointTransformBatches(mapper, trees[robot.key], None if driven else meter, series, previews[-1], trails)
                driven.append((robot, batches))
            if driven:  # a source used only by temporal edges is read there
                streams.append(fk_stream(observed(module_for(source).open_stream(source), times), driven, errors))
        streams.append(calibration_stream(plan.edges))
        if plan.output.joint_series:
            streams.append(series_names_stream(plan.robots))
        if plan.output.trails:
            streams.append(trail_statics_stream(plan.output.trails))
    if provenance is not None:
        streams.append(provenance_stream(plan, parts, provenance))
    # Temporal edges (a mobile base, a floating pelvis): their sources are opened again, see temporal_edges.py.
    temporal_streams, temporal_values = temporal_edge_streams(plan, errors) if parts != "model" else ([], [])
    bag_streams, bag_values = bag_edge_streams(plan) if parts != "model" else ([], [])  # a bag's /tf edges
    return _Pass(streams + temporal_streams + bag_streams, errors, mappers, [*temporal_values, *bag_values], meters, times, previews, pairs)


def _write(
    plan: RecordingPlan, parts: Parts, provenance: dict[str, str], on_note: Callable[[str], None], quiet: bool, rows_expected: int | None
) -> tuple[Path, dict[str, int], tuple[str, ...], SegmentSummary | None]:
    """One attempt: open the streams, write them to the partial file, check what the pass found, rename."""
    opened = _open(plan, parts, provenance, quiet, rows_expected)
    notes: list[str] = []

    def write(partial: Path) -> None:
        """The streams into the partial file, then the checks of what the pass found: a failed check leaves no file."""
        application_id, recording_id = plan.output.application_id, plan.output.recording_id
        opened.drain(lambda merged: merged.write_rrd(partial, application_id=application_id, recording_id=recording_id))
        notes.extend(opened.check(on_note))

    written = write_file_atomically(plan.output.path, write, "recording", plan.output.where)
    robots = tuple(r.key for r in plan.robots)
    summary = None if parts == "model" else segment_summary(robots, opened.times, opened.previews, tuple(notes), opened.pairs)
    return written, opened.rows(), tuple(notes), summary


def log_segment(plan: RecordingPlan, recording: RecordingStream, on_note: Callable[[str], None] = log_note) -> dict[str, int]:
    """One segment's model, FK and edges sent into the caller's recording as they are read (bounded memory, as a run).
    The checks of the pass (limits, NaN, zero rows) run after it and raise then: what was read is already sent. A
    source found out of time order part-way is sent again, whole and sorted (its earlier rows twice, same poses)."""

    def attempt(local: RecordingPlan) -> dict[str, int]:
        opened = _open(local, "all", None, True, None)
        opened.drain(recording.send_chunks)
        opened.check(on_note)
        return opened.rows()

    with local_inputs(plan) as local:  # remote sources fetched into this machine's cache, held while read
        return with_sorting_retry(lambda: attempt(local))

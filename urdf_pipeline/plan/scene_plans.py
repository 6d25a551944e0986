"""The whole plan and one recording of it: outputs, segments, the dataset, `ScenePlan`, `Plan`, `RecordingPlan`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from ..errors import UserError, Where, did_you_mean, listing
from .qa_plans import QaPlan
from .robot_plans import EdgePlan, RobotPlan, TemporalEdgePlan
from .source_plans import SourcePlan
from .trail_plans import TrailPlan

Layout = Literal["single", "split"]


@dataclass(frozen=True)
class OutputPlan:
    """Where one recording goes: a single-layout segment, a split layout's layer, or its model."""

    path: Path
    application_id: str
    recording_id: str
    where: Where
    joint_series: bool = False  # output.joint_series: the driven joints' values also as time series
    trails: tuple[TrailPlan, ...] = ()  # `trails:` (none in the split layout's model)


@dataclass(frozen=True)
class Segment:
    """One recording of a run: a LeRobot episode, a globbed input file, or the run's only input."""

    id: str  # the recording_id
    episode: int | None
    stem: str | None
    sources: tuple[SourcePlan, ...]  # this segment's own inputs (episode, file)
    output: Path
    frames: int | None  # rows expected, when the dataset's metadata says (LeRobot episode lengths)
    inputs: tuple[Path, ...]  # the files whose bytes this segment reads: part of its content hash


@dataclass(frozen=True)
class RemoteOutputs:
    """Outputs in one S3 bucket: each output path is under `staging` (this machine's mirror of it) until uploaded."""

    staging: Path
    url_root: str  # s3://BUCKET/

    def url_of(self, path: Path) -> str:
        return self.url_root + path.relative_to(self.staging).as_posix()


@dataclass(frozen=True)
class DatasetPlan:
    """The segments of a run and how they are written."""

    layout: Layout
    segments: tuple[Segment, ...]
    model: Path | None  # layout split: the static model asset
    manifest: Path
    where: Where  # output.segment, for errors about segments
    joint_series: bool = False  # output.joint_series: each segment also holds its driven joints' values as time series
    remote: RemoteOutputs | None = None  # outputs in S3: the staged paths above and their URLs


@dataclass(frozen=True)
class ScenePlan:
    """What every recording of a config shares, whatever it reads: the robots, the edges between their frames, the
    root frame. The base of the whole config's `Plan` and of one recording's `RecordingPlan`, which are otherwise
    apart so that no code reads one segment's sources or output from the dataset's plan."""

    config_path: Path
    robots: tuple[RobotPlan, ...]
    edges: tuple[EdgePlan, ...]
    root_frame: str
    temporal_edges: tuple[TemporalEdgePlan, ...]

    def robots_for(self, source: str) -> tuple[RobotPlan, ...]:
        return tuple(r for r in self.robots if r.source == source)


@dataclass(frozen=True)
class Plan(ScenePlan):
    """The whole config, compiled and frozen: the seam between checking and doing. Its segments each hold their own
    sources and output path; one recording's plan is `for_segment(segment)` (or `for_model()`): what a run executes."""

    dataset: DatasetPlan
    application_id: str  # every recording's (output.application_id)
    output_where: Where  # the config's `output`, for errors about what a run writes
    trails: tuple[TrailPlan, ...] = ()  # `trails:`, drawn by every segment's recording
    qa: QaPlan = QaPlan()  # `qa:`, the thresholds of the dataset's checks

    @property
    def segments(self) -> tuple[Segment, ...]:
        return self.dataset.segments

    def segment_named(self, wanted: str | None, option: str, first_by_default: bool) -> Segment:
        """The segment whose id is `wanted`; without one, the first (`first_by_default`) or the only one. `option` is
        how the user names it (`--segment`, `segment=`), for the error that lists the ids."""
        ids = [segment.id for segment in self.segments]
        if wanted is None:
            if first_by_default or len(ids) == 1:
                return self.segments[0]
            raise UserError(f"{len(ids)} segments; say which with {option} one of: {listing(ids)}", self.dataset.where)
        for segment in self.segments:
            if segment.id == wanted:
                return segment
        raise UserError(f"{option} {wanted}: no such segment (segments: {listing(ids)}){did_you_mean(wanted, ids)}", self.dataset.where)

    @property
    def review_segment(self) -> RecordingPlan:
        """The recording that plan, check, diff and init read: the first segment's, the one a run without --segment makes."""
        return self.for_segment(self.segments[0])

    def for_segment(self, segment: Segment) -> RecordingPlan:
        """The plan of one segment's recording: its own sources and output."""
        return self._recording(segment.sources, segment.output, segment.id)

    def for_model(self) -> RecordingPlan:
        """The plan of the split layout's model asset: no source is read."""
        assert self.dataset.model is not None, "for_model needs the split layout"
        return self._recording((), self.dataset.model, MODEL_RECORDING_ID)

    def _recording(self, sources: tuple[SourcePlan, ...], path: Path, recording_id: str) -> RecordingPlan:
        series = self.dataset.joint_series and bool(sources)  # the split layout's model holds no values
        trails = self.trails if sources else ()
        output = OutputPlan(path, self.application_id, recording_id, self.output_where, series, trails)
        return RecordingPlan(self.config_path, self.robots, self.edges, self.root_frame, self.temporal_edges, sources, output, self.qa)


@dataclass(frozen=True)
class RecordingPlan(ScenePlan):
    """The plan of ONE recording (a segment, or the split layout's model), made by `Plan.for_segment`/`for_model`:
    what execute writes and the API logs. It knows nothing of the other segments."""

    sources: tuple[SourcePlan, ...]  # this recording's own inputs (its episode, its file); none for the model
    output: OutputPlan
    qa: QaPlan = QaPlan()  # the config's `qa:` thresholds (compare's calibration bias is measured in the run's pass)

    def source(self, name: str) -> SourcePlan:
        return next(s for s in self.sources if s.name == name)


MODEL_RECORDING_ID = "urdf_model"  # the split layout's model asset is a recording of its own, not a segment

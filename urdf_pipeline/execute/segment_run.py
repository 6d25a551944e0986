"""One segment's recording, written by a worker (a process of the local pool, a Ray task, or the main process).

A job carries everything it needs (the plan for that one recording), so it can run anywhere; its result says what
happened instead of raising, so one failing segment does not stop the others.
"""

from __future__ import annotations

import logging
import resource
import time
import traceback
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

from ..errors import UserError
from ..logs import note, process_identity, warnings_logged, worker_logging
from ..plan import Plan, RecordingPlan, Segment
from .manifest_entry import SegmentSummary
from .segment import Parts

Status = Literal["written", "skipped", "failed", "bug", "interrupted"]


@dataclass(frozen=True)
class SegmentJob:
    """One recording to write: the run's plan and which segment of it (None: the split layout's model)."""

    segment: Segment | None
    parts: Parts
    label: str  # the segment id, or "model"
    output: Path
    content_hash: str
    frames_expected: int | None = None
    verbose: bool = False  # the run's only job, in the main process: print progress and notes as they come
    log_level: int = logging.INFO  # the run's process's level for the `urdf_pipeline` logger (--quiet, --verbose)
    driver: str = ""  # host:pid of the run's process: a worker elsewhere sets up its own logging at `log_level`
    run_plan: Plan | None = None  # None when the worker was given the run's plan once, at its start (install_run_plan)
    upload: str | None = None  # outputs in S3: the recording's URL (written to this machine's staging folder first)

    def plan(self) -> RecordingPlan:
        """This job's recording, cut from the run's plan: the segment's sources and output, or the model's. An output
        bound for S3 is written to THIS machine's staging folder (a Ray worker's is not the driver's)."""
        run_plan = self.run_plan or _INSTALLED[0]
        recording = run_plan.for_model() if self.segment is None else run_plan.for_segment(self.segment)
        if self.upload is None:
            return recording
        from ..remote import parse_url, staged_path

        return replace(recording, output=replace(recording.output, path=staged_path(parse_url(self.upload))))


_INSTALLED: list[Plan] = []


def install_run_plan(plan: Plan) -> None:
    """A pool worker's initializer: the run's plan (the robots' URDF text, ...) is sent once, not with every job."""
    _INSTALLED[:] = [plan]


@dataclass(frozen=True)
class SegmentResult:
    label: str
    output: Path
    status: Status
    content_hash: str
    frames: int = 0
    seconds: float = 0.0
    reason: str = ""  # the error lines of a failed segment, the traceback of a bug
    bytes: int = 0
    notes: tuple[str, ...] = ()
    worker: str = ""  # host:pid of the process that ran it
    peak_rss_mib: float = 0.0  # that process's peak resident memory so far
    summary: SegmentSummary | None = None  # a written segment's time ranges, notes and preview, for the manifest
    etag: str = ""  # an output uploaded to S3: its ETag there


def run_segment(job: SegmentJob) -> SegmentResult:
    from .segment import execute

    started = time.perf_counter()
    notes: list[str] = []
    if job.driver:
        worker_logging(job.log_level, job.driver)

    def on_note(text: str) -> None:
        notes.append(text)
        if job.verbose:
            note(text)

    failed = SegmentResult(job.label, job.output, "failed", job.content_hash)
    try:
        provenance = {"content_sha256": job.content_hash}
        with warnings_logged():
            # A meter only for the run's one segment (`verbose`): in a many-segment run, the run's progress says it
            result = execute(job.plan(), job.parts, provenance, on_note=on_note, quiet=not job.verbose, rows_expected=job.frames_expected)
    except UserError as exc:
        return _finished(replace(failed, reason="\n".join(exc.lines()), notes=tuple(notes)), started)
    except Exception:
        return _finished(replace(failed, status="bug", reason=traceback.format_exc(), notes=tuple(notes)), started)
    frames = max(result.rows.values(), default=0)
    size = result.output.stat().st_size
    written = replace(failed, status="written", frames=frames, bytes=size, notes=tuple(notes), summary=result.summary)
    if job.upload is not None:
        try:
            written = replace(written, etag=_uploaded(job, result.output))
        except UserError as exc:
            return _finished(replace(failed, reason="\n".join(exc.lines()), notes=tuple(notes)), started)
    return _finished(written, started)


CONTENT_METADATA = "urdf-pipeline-content-sha256"  # an uploaded recording's content hash, as S3 user metadata


def _uploaded(job: SegmentJob, staged: Path) -> str:
    """The staged recording uploaded to its URL (whole or not at all), then removed here: a worker's disk holds one
    recording at a time. Its content hash goes with it, so a later run knows the object as its own."""
    from ..remote import parse_url, upload

    assert job.upload is not None
    try:
        uploaded = upload(staged, parse_url(job.upload), None, {CONTENT_METADATA: job.content_hash})
    finally:
        staged.unlink(missing_ok=True)
    return uploaded.version


def _finished(result: SegmentResult, started: float) -> SegmentResult:
    """With the time it took and the worker's identity and peak memory (KiB on Linux), for the summary and --report."""
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    worker = process_identity()
    return replace(result, seconds=time.perf_counter() - started, worker=worker, peak_rss_mib=peak_mib)

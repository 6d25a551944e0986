"""Run every segment of a plan: skip what is up to date, run the rest on an executor, keep the manifest current.

One failing segment does not stop the others; Ctrl-C or SIGTERM stops the run, removes partial files and keeps the
manifest true to the complete files. Before anything is computed, every file the run would replace must be one the
pipeline wrote, every output folder must take files, and partial files that killed runs left are removed.
"""

from __future__ import annotations

import os
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import Problems, UserError
from ..execute import Parts, SegmentJob, SegmentResult, remove_stale_partials, require_ours, require_writable, run_segment
from ..plan import Plan
from ..progress import LOGGER, SegmentProgress, process_identity
from .executors import ExecutorName, executor_for
from .fingerprint import file_hashes_used, model_hash, remember_file_hashes, segment_hashes
from .interrupts import signal_name, signal_number
from .manifest import Manifest

if TYPE_CHECKING:
    from .catalog import CatalogReport


@dataclass(frozen=True)
class RunOptions:
    jobs: int = 1
    executor: ExecutorName = "local"
    ray_address: str | None = None
    force: bool = False
    verbose: bool = False  # one segment in this process: its own progress lines and notes, as a plain run prints them


@dataclass(frozen=True)
class DatasetRun:
    results: tuple[SegmentResult, ...]  # the model first (split layout), then the segments in order
    seconds: float
    manifest: Path
    interrupted: bool
    signal: int = 0  # what interrupted it: SIGINT (Ctrl-C) or SIGTERM
    blueprint: Path | None = None  # the run's blueprint, when some output was written or is up to date


def build_jobs(plan: Plan) -> list[SegmentJob]:
    jobs = []
    if plan.dataset.layout == "split" and plan.dataset.model is not None:
        jobs.append(SegmentJob(None, "model", "model", plan.dataset.model, model_hash(plan), run_plan=plan))
    parts: Parts = "layer" if plan.dataset.layout == "split" else "all"
    hashes = segment_hashes(plan, with_model=parts == "all")
    for segment in plan.dataset.segments:
        jobs.append(SegmentJob(segment, parts, segment.id, segment.output, hashes[segment.id], segment.frames, run_plan=plan))
    return jobs


def run_dataset(plan: Plan, options: RunOptions, progress: SegmentProgress | None = None) -> DatasetRun:
    started = time.perf_counter()
    manifest = Manifest.load(plan.dataset.manifest, plan.application_id, plan.dataset.layout, plan.config_path, plan.output_where)
    remember_file_hashes(manifest.files)
    jobs = build_jobs(plan)
    # Hashes of files this run did not read (other episodes: `--episodes`) are kept while the file is there, so that
    # the next full re-run does not read them again; a changed file is hashed again anyway (size and mtime).
    kept = {path: entry for path, entry in manifest.files.items() if os.path.exists(path)}
    manifest.files = {**kept, **file_hashes_used()}
    results: dict[str, SegmentResult] = {}
    to_run: list[SegmentJob] = []
    for job in jobs:
        fresh = manifest.up_to_date(job.label, job.output, job.content_hash)
        if not fresh and manifest.entry(job.label) is None:  # no manifest (deleted, another machine): the file says
            fresh = _adopt_if_written(job, manifest)
        if fresh and not options.force:
            results[job.label] = SegmentResult(job.label, job.output, "skipped", job.content_hash, reason="up to date")
        else:
            to_run.append(job)
    _prepare_outputs(plan, jobs, to_run, manifest)
    if progress is not None:
        progress.start(len(jobs), sum(j.frames_expected or 0 for j in to_run), skipped=len(jobs) - len(to_run))

    def on_done(job: SegmentJob, result: SegmentResult) -> None:
        results[job.label] = result
        if result.status == "written":
            extra = {"episode": job.segment.episode} if job.segment is not None else {}
            manifest.record(job.label, job.output, job.content_hash, result.frames, extra)
            manifest.write(every_seconds=1.0)
        if progress is not None:
            progress.done(result, job.frames_expected)

    def on_crash(job: SegmentJob, error: BaseException) -> None:
        reason = "".join(traceback.format_exception(error))
        on_done(job, SegmentResult(job.label, job.output, "bug", job.content_hash, reason=reason))

    if options.jobs != 1:  # the model, then the longest first: parallel workers finish together (no long one left last)
        to_run.sort(key=lambda job: (job.segment is not None, -(job.frames_expected or 0)))
    work: Callable[[SegmentJob], SegmentResult] = run_segment
    if options.verbose and len(to_run) == 1 and options.executor == "local":
        to_run = [replace(to_run[0], verbose=True)]
    level, driver = LOGGER.getEffectiveLevel(), process_identity()  # workers elsewhere log as this process does
    to_run = [replace(job, log_level=level, driver=driver) for job in to_run]
    interrupted = 0
    try:
        executor_for(options.executor, options.jobs, options.ray_address, plan).run(work, to_run, on_done, on_crash)
    except KeyboardInterrupt as stop:  # Ctrl-C, or SIGTERM (interrupts.Terminated)
        interrupted = signal_number(stop)
        _remove_partial_files([job.output for job in to_run])
        for job in to_run:
            if job.label in results:
                continue
            if _adopt_if_written(job, manifest):  # finished by a worker stopped before its result arrived
                reason = f"finished as {signal_name(interrupted)} came"
                results[job.label] = SegmentResult(job.label, job.output, "written", job.content_hash, reason=reason)
            else:
                results[job.label] = SegmentResult(job.label, job.output, "interrupted", job.content_hash, reason=signal_name(interrupted))
    finally:
        if progress is not None:
            progress.finish()
        manifest.write()
    ordered = tuple(results[job.label] for job in jobs)
    blueprint = None
    if not interrupted and any(r.status in ("written", "skipped") for r in ordered):
        blueprint = _blueprint(plan, manifest)
    return DatasetRun(ordered, time.perf_counter() - started, manifest.path, bool(interrupted), interrupted, blueprint)


def _blueprint(plan: Plan, manifest: Manifest) -> Path:
    """The run's blueprint, written unless the manifest says the one there is current."""
    from ..execute import blueprint_key, blueprint_path, write_blueprint

    path, key = blueprint_path(plan), blueprint_key(plan)
    if not manifest.blueprint_up_to_date(path, key):
        manifest.record_blueprint(write_blueprint(plan), key)
        manifest.write()
    return path


def _prepare_outputs(plan: Plan, jobs: list[SegmentJob], to_run: list[SegmentJob], manifest: Manifest) -> None:
    """Before computing anything: no file the pipeline did not write would be replaced (not even with --force), every
    folder written to takes files, and the partial files of killed runs are gone. Every refusal at once, exit 1."""
    from ..execute import blueprint_key, blueprint_path

    where = plan.output_where
    problems = Problems()
    for job in to_run:
        try:
            require_ours(job.output, "recording", where)
        except UserError as error:
            problems.extend(error)
    blueprint = blueprint_path(plan)
    try:
        if not manifest.blueprint_up_to_date(blueprint, blueprint_key(plan)):  # recorded as ours: no Rerun needed
            require_ours(blueprint, "blueprint", where)
    except UserError as error:
        problems.extend(error)
    for directory in dict.fromkeys([*(job.output.parent for job in to_run), plan.dataset.manifest.parent]):
        try:
            require_writable(directory, where)
        except UserError as error:
            problems.extend(error)
    problems.raise_if_any()
    remove_stale_partials(path.parent for path in [*(job.output for job in jobs), plan.dataset.manifest, blueprint])


def _adopt_if_written(job: SegmentJob, manifest: Manifest) -> bool:
    """The job's output exists with the content hash it would be written with: list it in the manifest."""
    from ..execute import stored_content_hash

    if not job.output.is_file() or stored_content_hash(job.output, job.parts) != job.content_hash:
        return False
    manifest.record(job.label, job.output, job.content_hash, job.frames_expected or 0, {})
    return True


def _remove_partial_files(outputs: list[Path]) -> None:
    """A worker stopped mid-write leaves `.NAME.partial-PID` beside its target; only complete files may remain."""
    for output in outputs:
        for partial in output.parent.glob(f".{output.name}.partial-*"):
            partial.unlink(missing_ok=True)


def register_outputs(run: DatasetRun, url: str, dataset: str, layer: str) -> CatalogReport:
    """Register what the run wrote or found up to date: the model as the dataset's asset, each segment under `layer`."""
    from .catalog import register_in_catalog

    usable = [r for r in run.results if r.status in ("written", "skipped")]
    model = next((r.output for r in usable if r.label == "model"), None)
    return register_in_catalog(url, dataset, layer, model, [(r.label, r.output) for r in usable if r.label != "model"])

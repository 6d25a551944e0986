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
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ExitCode, Problems, UserError
from ..execute import (
    Parts,
    SegmentJob,
    SegmentResult,
    folders_removed_if_left_empty,
    remove_stale_partials,
    require_ours,
    require_writable,
)
from ..logs import LOGGER, SegmentProgress, process_identity
from ..plan import Plan, RemoteOutputs
from ..process import signal_name, stop_signal
from .executors import ExecutorName, run_jobs
from .fingerprint import file_hashes_used, model_hash, remember_file_hashes, segment_hashes
from .manifest import Manifest
from .remote_outputs import bucket_state, fetch_manifest, fresh_in_bucket, input_versions, upload_run_files

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
    """What a run did, segment by segment. The command line and the API read what to print, return or raise from it,
    so they count written, failed and bug segments alike."""

    results: tuple[SegmentResult, ...]  # the model first (split layout), then the segments in order
    seconds: float
    manifest: Path
    interrupted: bool
    signal: int = 0  # what interrupted it: SIGINT (Ctrl-C) or SIGTERM
    blueprint: Path | None = None  # the run's blueprint, when some output was written or is up to date
    remote: RemoteOutputs | None = None  # outputs in S3: their staged paths' URLs
    not_rewritten: int = 0  # of the up-to-date outputs, those `--force` asked for again that a stop left as they were

    @property
    def usable(self) -> tuple[SegmentResult, ...]:
        """Written by this run or already up to date: the recordings there are to open, register or send."""
        return tuple(r for r in self.results if r.status in ("written", "skipped"))

    @property
    def outputs(self) -> tuple[Path, ...]:
        """The paths of the usable recordings, in the results' order: what `run` prints on stdout and the API returns."""
        return tuple(r.output for r in self.usable)

    @property
    def locations(self) -> tuple[str, ...]:
        """Where the usable recordings are: their paths, or their URLs when the outputs are in S3."""
        remote = self.remote
        return tuple(remote.url_of(path) if remote is not None else str(path) for path in self.outputs)

    @property
    def failed(self) -> tuple[SegmentResult, ...]:
        """The segments refused by a user error (their error lines in `reason`)."""
        return tuple(r for r in self.results if r.status == "failed")

    @property
    def bugs(self) -> tuple[SegmentResult, ...]:
        """The segments that hit a bug (their traceback in `reason`)."""
        return tuple(r for r in self.results if r.status == "bug")

    @property
    def exit_status(self) -> int:
        """The command's exit status: the signal's when interrupted, else a bug's, else a user error's if a segment
        failed, else OK."""
        if self.interrupted:
            return ExitCode.for_signal(self.signal)
        if self.bugs:
            return ExitCode.BUG
        return ExitCode.USER_ERROR if self.failed else ExitCode.OK


def build_jobs(plan: Plan) -> list[SegmentJob]:
    jobs = []
    remote = plan.dataset.remote

    def url(path: Path) -> str | None:
        return remote.url_of(path) if remote is not None else None

    if plan.dataset.layout == "split" and plan.dataset.model is not None:
        model = plan.dataset.model
        jobs.append(SegmentJob(None, "model", "model", model, model_hash(plan), run_plan=plan, upload=url(model)))
    parts: Parts = "layer" if plan.dataset.layout == "split" else "all"
    hashes = segment_hashes(plan, with_model=parts == "all")
    for segment in plan.dataset.segments:
        output = segment.output
        jobs.append(SegmentJob(segment, parts, segment.id, output, hashes[segment.id], segment.frames, run_plan=plan, upload=url(output)))
    return jobs


def run_dataset(
    plan: Plan, options: RunOptions, progress: SegmentProgress | None = None, ready: Callable[[], None] | None = None
) -> DatasetRun:
    """Every recording of the plan that is not up to date, written on the executor `options` name; see the module.
    `ready` is called once every refusal before the work is behind (a refused run says nothing of work it never did).
    An output folder the run made and wrote nothing into is removed (a refused or stopped run leaves none behind)."""
    folders = [*(segment.output.parent for segment in plan.dataset.segments), plan.dataset.manifest.parent]
    with folders_removed_if_left_empty(folders + ([plan.dataset.model.parent] if plan.dataset.model is not None else [])):
        return _run(plan, options, progress, ready)


def _run(plan: Plan, options: RunOptions, progress: SegmentProgress | None, ready: Callable[[], None] | None) -> DatasetRun:
    started = time.perf_counter()
    remote = plan.dataset.remote
    if remote is not None and options.executor == "ray" and plan.dataset.layout != "split":
        raise UserError(
            "with outputs in S3 on a Ray cluster, use layout: split: the meshes are read once, where the config is, and "
            "each node writes only its layers (a single-layout recording would need the mesh files on every node)",
            plan.output_where,
        )
    state = None
    if remote is not None:
        state = bucket_state(plan, remote)  # one listing of the outputs' prefix
        fetch_manifest(plan, remote, state)  # the last run's, from the bucket (it may have run on another machine)
    manifest = _manifest(plan)
    jobs = build_jobs(plan)
    in_bucket = fresh_in_bucket(jobs, manifest, state, plan.output_where) if state is not None else None
    results, to_run = _up_to_date(jobs, manifest, options.force, in_bucket)
    _prepare_outputs(plan, jobs, to_run, manifest)
    if ready is not None:
        ready()
    if progress is not None:
        progress.start(len(jobs), sum(j.frames_expected or 0 for j in to_run), skipped=len(jobs) - len(to_run))
    to_run = _dispatched(to_run, options)
    keeper = _Bookkeeper(results, manifest, progress, {job.label: _identity(job.output) for job in to_run})
    interrupted = 0
    try:
        here, elsewhere = _where_jobs_run(plan, options, to_run)
        if here:  # the split layout's model on a cluster without the config's disk: its meshes are read here
            run_jobs("local", 1, None, plan, here, keeper.done, keeper.crashed)
        run_jobs(options.executor, options.jobs, options.ray_address, plan, elsewhere, keeper.done, keeper.crashed)
    except KeyboardInterrupt as stop:  # Ctrl-C, or SIGTERM (process.Stopped)
        interrupted = stop_signal(stop)
        _remove_partial_files([job.output for job in to_run])
        keeper.stopped(to_run, interrupted)
    finally:
        if progress is not None:
            progress.finish()
        manifest.write()
        if remote is not None and interrupted:
            upload_run_files(plan, remote, None)  # what was uploaded before the stop, listed
    ordered = tuple(results[job.label] for job in jobs)
    blueprint = None
    if not interrupted and any(r.status in ("written", "skipped") for r in ordered):
        blueprint = _blueprint(plan, manifest)
    if remote is not None and not interrupted:
        upload_run_files(plan, remote, blueprint)  # the manifest last
    seconds = time.perf_counter() - started
    return DatasetRun(ordered, seconds, manifest.path, bool(interrupted), interrupted, blueprint, remote, keeper.not_rewritten)


def _manifest(plan: Plan) -> Manifest:
    """The run's manifest, with the hashes of the input files it knows (a file unchanged since is not read again)."""
    manifest = Manifest.load(plan.dataset.manifest, plan.application_id, plan.dataset.layout, plan.config_path, plan.output_where)
    remember_file_hashes(manifest.files)
    return manifest


def _up_to_date(
    jobs: list[SegmentJob], manifest: Manifest, force: bool, in_bucket: set[str] | None = None
) -> tuple[dict[str, SegmentResult], list[SegmentJob]]:
    """The results of the jobs whose output is up to date (skipped unless `force`), and the jobs to run. `in_bucket`:
    outputs in S3, the labels `fresh_in_bucket` found up to date there."""
    # Hashes of files this run did not read (other episodes: `--episodes`) are kept while the file is there, so that
    # the next full re-run does not read them again; a changed file is hashed again anyway (size and mtime).
    kept = {path: entry for path, entry in manifest.files.items() if os.path.exists(path)}
    manifest.files = {**kept, **file_hashes_used()}
    results: dict[str, SegmentResult] = {}
    to_run: list[SegmentJob] = []
    for job in jobs:
        fresh = job.label in in_bucket if in_bucket is not None else manifest.up_to_date(job.label, job.output, job.content_hash)
        if not fresh and in_bucket is None and manifest.entry(job.label) is None:  # no manifest (deleted, another machine)
            fresh = _adopt_if_written(job, manifest)
        if fresh and not force:
            results[job.label] = SegmentResult(job.label, job.output, "skipped", job.content_hash, reason="up to date")
        else:
            to_run.append(job)
    return results, to_run


def _where_jobs_run(plan: Plan, options: RunOptions, to_run: list[SegmentJob]) -> tuple[list[SegmentJob], list[SegmentJob]]:
    """(jobs this process runs first, jobs for the executor). With outputs in S3 on Ray, the cluster's nodes are taken
    to share no disk with this one: they get the plan and URLs (each fetches its inputs into its own cache and uploads
    its layer), while the split layout's model, which reads the meshes where the config is, is written here."""
    if options.executor != "ray" or plan.dataset.remote is None:
        return [], to_run
    return [job for job in to_run if job.segment is None], [job for job in to_run if job.segment is not None]


def _dispatched(to_run: list[SegmentJob], options: RunOptions) -> list[SegmentJob]:
    """The jobs as the executor gets them: in the order they should start, logging as this process does."""
    if options.jobs != 1:  # the model, then the longest first: parallel workers finish together (no long one left last)
        to_run = sorted(to_run, key=lambda job: (job.segment is not None, -(job.frames_expected or 0)))
    if options.verbose and len(to_run) == 1 and options.executor == "local":
        to_run = [replace(to_run[0], verbose=True)]
    level, driver = LOGGER.getEffectiveLevel(), process_identity()  # workers elsewhere log as this process does
    return [replace(job, log_level=level, driver=driver) for job in to_run]


@dataclass
class _Bookkeeper:
    """Each job's result as the executor reports it: kept, recorded in the manifest when written, shown by the progress
    bar; and, when the run is stopped, what became of the jobs that had not reported."""

    results: dict[str, SegmentResult]
    manifest: Manifest
    progress: SegmentProgress | None
    before: dict[str, tuple[int, int, int, int] | None]  # each job's output as the run found it (`_identity`)
    not_rewritten: int = 0

    def done(self, job: SegmentJob, result: SegmentResult) -> None:
        self.results[job.label] = result
        if result.status == "written":
            extra: dict[str, Any] = {"episode": job.segment.episode} if job.segment is not None else {}
            if result.summary is not None:
                extra["summary"] = result.summary.as_json()
            if job.upload is not None:  # uploaded by the worker, its staged file removed
                extra.update(url=job.upload, etag=result.etag)
            inputs = input_versions(job.segment)
            if inputs:  # remote inputs: the versions it was made from
                extra["inputs"] = inputs
            self.manifest.record(job.label, job.output, job.content_hash, result.frames, extra, size=result.bytes)
            self.manifest.write(every_seconds=1.0)
        if self.progress is not None:
            self.progress.done(result, job.frames_expected)

    def crashed(self, job: SegmentJob, error: BaseException) -> None:
        reason = "".join(traceback.format_exception(error))
        self.done(job, SegmentResult(job.label, job.output, "bug", job.content_hash, reason=reason))

    def stopped(self, jobs: list[SegmentJob], signum: int) -> None:
        """After Ctrl-C or SIGTERM (partial files removed), what became of each job without a result: written (a
        worker renamed its file into place as the signal came), up to date (an earlier run's file, untouched, as the
        manifest lists it: `--force` had asked for it again), or not done (an earlier file, out of date, left as it
        was). Only a file this run put in place is "written"."""
        stop = signal_name(signum)
        for job in jobs:
            if job.label in self.results:
                continue
            now = _identity(job.output)
            if now is not None and now != self.before.get(job.label) and _adopt_if_written(job, self.manifest):
                result = SegmentResult(
                    job.label, job.output, "written", job.content_hash, frames=job.frames_expected or 0, reason=f"finished as {stop} came"
                )
            elif (
                now is not None and now == self.before.get(job.label) and self.manifest.up_to_date(job.label, job.output, job.content_hash)
            ):
                result = SegmentResult(
                    job.label,
                    job.output,
                    "skipped",
                    job.content_hash,
                    reason=f"up to date (an earlier run's); not rewritten: {stop} came first",
                )
                self.not_rewritten += 1
            else:
                kept = "; the earlier file, out of date, is left as it was" if now is not None else ""
                result = SegmentResult(job.label, job.output, "interrupted", job.content_hash, reason=f"not done: {stop} came first{kept}")
            self.results[job.label] = result


def _identity(path: Path) -> tuple[int, int, int, int] | None:
    """What tells a file renamed into place from the one that was there (device, inode, size, mtime), None if absent."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)


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
    blueprint = blueprint_path(plan)
    checks = [partial(require_ours, job.output, "recording", where) for job in to_run]
    if not manifest.blueprint_up_to_date(blueprint, blueprint_key(plan)):  # recorded as ours: no Rerun needed
        checks.append(partial(require_ours, blueprint, "blueprint", where))
    checks += [
        partial(require_writable, d, where) for d in dict.fromkeys([*(job.output.parent for job in to_run), plan.dataset.manifest.parent])
    ]
    problems = Problems()
    for check in checks:
        try:
            check()
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
        for left in output.parent.glob(f".{output.name}.partial-*"):
            left.unlink(missing_ok=True)


def register_outputs(run: DatasetRun, url: str, dataset: str, layer: str) -> CatalogReport:
    """Register what the run wrote or found up to date: the model as the dataset's asset, each segment under `layer`."""
    from .catalog import register_in_catalog

    def where(result: SegmentResult) -> Path | str:  # an output in S3 by its URL
        return run.remote.url_of(result.output) if run.remote is not None else result.output

    model = next((where(r) for r in run.usable if r.label == "model"), None)
    return register_in_catalog(url, dataset, layer, model, [(r.label, where(r)) for r in run.usable if r.label != "model"])

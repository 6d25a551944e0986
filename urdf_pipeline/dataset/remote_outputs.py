"""A run whose outputs go to S3 (`DatasetPlan.remote`): the bucket's side of the manifest and the up-to-date check.

- Before: the manifest is downloaded from its URL into the staging folder (the last run may have been on another
  machine), and the outputs' prefix is listed once: an output is up to date when its manifest entry has the same
  content hash and the object still has the ETag the manifest recorded. An object at an output's URL that the
  manifest does not list is read for our metadata (one HEAD): written by urdf-pipeline with the same content hash, it
  is adopted (a run killed before its manifest was uploaded); with another hash, it is ours to replace; without our
  metadata, it is somebody else's and the run refuses, as it never overwrites a file it did not write.
- During: each worker uploads its recording (execute's `SegmentJob.upload`): an object appears whole or not at all.
- After (and when stopped): the blueprint and then the manifest are uploaded, the manifest last.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import Problems, UserError, Where, shown
from ..execute import CONTENT_METADATA, SegmentJob
from ..plan import Plan, RemoteDataset, RemoteObject, RemoteOutputs, Segment
from ..remote import download, fetched, listing, metadata_of, parse_url, upload
from .manifest import Manifest, OutputKind, SegmentEntry, run_output


@dataclass(frozen=True)
class BucketState:
    """What the outputs' prefix holds now, by URL (one listing)."""

    objects: dict[str, RemoteObject]
    prefix: str = ""  # the prefix listed: every output of the run is under it


def bucket_state(plan: Plan, remote: RemoteOutputs) -> BucketState:
    """One listing of the deepest prefix every output of the plan shares: its recordings, model and manifest (and so
    the blueprint beside the manifest)."""
    paths = [s.output for s in plan.dataset.segments] + [p for p in (plan.dataset.model, plan.dataset.manifest) if p is not None]
    head = os.path.commonprefix([remote.url_of(path) for path in paths])
    prefix = head[: head.rfind("/") + 1]
    return BucketState({o.url: o for o in listing(parse_url(prefix), plan.output_where)}, prefix)


def fetch_manifest(plan: Plan, remote: RemoteOutputs, state: BucketState) -> None:
    """The bucket's manifest, put where the run reads it (the staging folder), or no file when there is none."""
    path = plan.dataset.manifest
    path.parent.mkdir(parents=True, exist_ok=True)
    found = state.objects.get(remote.url_of(path))
    if found is None:
        path.unlink(missing_ok=True)
        return
    download(found, path, plan.output_where)


def fresh_in_bucket(jobs: list[SegmentJob], manifest: Manifest, state: BucketState, where: Where | None) -> set[str]:
    """The labels of the jobs whose object is up to date: the manifest's entry has the job's content hash and the
    object still has the ETag the entry recorded, or (an object the manifest does not list as it is) our metadata
    says this content hash: a run stopped before its manifest went up, recorded now. An object without our metadata
    is another writer's: every such one is refused at once, before anything is computed."""
    fresh: set[str] = set()
    problems = Problems()
    for job in jobs:
        entry = manifest.entry(job.label)
        found = state.objects.get(job.upload or "")
        if found is None:
            continue
        if entry is not None and entry.get("etag") == found.version:  # ours, as the manifest recorded it
            if entry.get("content_sha256") == job.content_hash:
                fresh.add(job.label)
            continue
        try:
            if _adopted(job, manifest, found, where):
                fresh.add(job.label)
        except UserError as error:
            problems.extend(error)
    problems.raise_if_any()
    return fresh


def _adopted(job: SegmentJob, manifest: Manifest, found: RemoteObject, where: Where | None) -> bool:
    """`found`, at the job's URL and not listed by the manifest as it is, by its metadata (one HEAD): ours with this
    content hash is recorded and up to date; ours with another hash may be replaced; without our metadata it is
    another writer's (a UserError: the run never replaces it)."""
    written_hash = metadata_of(parse_url(found.url), where).get(CONTENT_METADATA)
    if written_hash is None:
        raise UserError(
            f"cannot write {shown(found.url)}: an object is there that urdf-pipeline did not write; it never overwrites one "
            "(not even with --force): delete or move it, or choose another output prefix",
            where,
        )
    if written_hash != job.content_hash:
        return False
    extra = {"url": found.url, "etag": found.version, **({"episode": job.segment.episode} if job.segment is not None else {})}
    manifest.record(job.label, job.output, job.content_hash, job.frames_expected or 0, extra, size=found.size)
    return True


def upload_run_files(plan: Plan, remote: RemoteOutputs, blueprint: Path | None) -> None:
    """The blueprint (when the run wrote or kept one), then the manifest: uploaded last, so a reader of the bucket
    never sees a manifest listing an object that is not there."""
    for path in (blueprint, plan.dataset.manifest):
        if path is not None and path.is_file():
            upload(path, parse_url(remote.url_of(path)), plan.output_where)


@contextmanager
def local_outputs(
    plan: Plan, entries: list[SegmentEntry], state: BucketState
) -> Iterator[tuple[list[SegmentEntry], Path | None, Path | None]]:
    """For a reader of a run's outputs in S3 (`browse`): the entries with their recordings fetched into this machine's
    download cache (each the version the manifest recorded: a replaced object is an error naming it), the model and
    the blueprint likewise; held in the cache while the block runs. Entries of the manifest the bucket no longer
    holds as recorded are left out, as local entries whose file is gone are. The manifest is data from whoever wrote
    the bucket: an entry whose URL is not under the run's outputs prefix is refused before anything is fetched, and
    every fetched file must be a recording (a blueprint) the tool wrote (`run_output`), as a local output must."""
    remote = plan.dataset.remote
    assert remote is not None
    objects = state.objects
    manifest = Manifest.load(plan.dataset.manifest, plan.application_id, plan.dataset.layout, plan.config_path, plan.output_where)
    model_entry = manifest.model or {}
    model_where = Where(manifest.path, 0, "model.url")
    named: set[str] = set()
    for url, where in [(e.url, e.where) for e in entries] + ([(model_entry.get("url"), model_where)] if model_entry else []):
        if not isinstance(url, str) or not url.startswith(state.prefix):
            raise UserError(
                f"names {shown(str(url))}, which is not under the run's outputs ({shown(state.prefix)}); a manifest may name "
                "only the objects the run wrote (`urdf-pipeline run CONFIG --force` writes them again)",
                where,
            )
        if url in named:
            raise UserError(f"names {shown(url)} a second time: each segment has a recording of its own", where)
        named.add(url)

    def as_recorded(url: object, etag: object) -> RemoteObject | None:
        found = objects.get(str(url))
        return found if found is not None and found.version == etag else None

    wanted = [(e, found) for e in entries if (found := as_recorded(e.url, e.etag)) is not None]
    model = as_recorded(model_entry.get("url"), model_entry.get("etag"))
    blueprint = objects.get(remote.url_of(plan.dataset.manifest.parent / f"{plan.config_path.stem}.rbl"))
    targets = [found for _, found in wanted] + [found for found in (model, blueprint) if found is not None]

    def download_one(found: RemoteObject) -> None:  # into the cache, FETCH_THREADS at a time (latency, not CPU)
        with fetched(found, plan.output_where):
            pass

    with ThreadPoolExecutor(FETCH_THREADS, thread_name_prefix="fetch-outputs") as pool:
        list(pool.map(download_one, targets))
    with ExitStack() as held:  # then each held in the cache (found there) while the caller links it

        def local(found: RemoteObject, kind: OutputKind, where: Where | None) -> Path:
            path = run_output(held.enter_context(fetched(found, plan.output_where)), kind, "the object", where, None, found.url)
            assert path is not None  # held in the cache: it is there
            return path

        yield (
            [replace(e, path=local(found, "recording", e.where)) for e, found in wanted],
            local(model, "recording", model_where) if model is not None else None,
            local(blueprint, "blueprint", plan.output_where) if blueprint is not None else None,
        )


FETCH_THREADS = 8


def input_versions(segment: Segment | None) -> dict[str, str]:
    """What a segment's remote inputs were (URL -> ETag or Hub commit), for its manifest entry: the run read exactly
    these, and a re-run with the same ones reads nothing again."""
    found: dict[str, str] = {}
    for source in segment.sources if segment is not None else ():
        remote = getattr(source, "remote", None)
        if isinstance(remote, RemoteObject):
            found[remote.url] = remote.version
        elif isinstance(remote, RemoteDataset):
            found.update((o.url, o.version) for o in (*remote.meta, *remote.data))
    return found

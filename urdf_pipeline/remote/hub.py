"""Hugging Face Hub datasets through the Hub's own client, `huggingface_hub`: a revision resolved to its commit, a
dataset's metadata files, one file at a commit, all kept in the client's own cache (docs/remote.md says why).

The client's environment (HF_HUB_CACHE, HF_HOME, HF_HUB_OFFLINE, HF_ENDPOINT; the token: HF_TOKEN or `hf auth login`'s)
is read when each call is made, so that a long-lived process, a test, sees the environment it runs in. No token is
ever in a message.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

from ..errors import UserError, Where, listing, shown
from ..plan import RemoteObject
from .locations import RemoteUrl, parse_url

OFFLINE_ENV = "HF_HUB_OFFLINE"
COMMIT = re.compile(r"^[0-9a-f]{40}$")
TRUE = {"1", "ON", "YES", "TRUE"}  # what the client takes for a true HF_HUB_OFFLINE


def _client() -> ModuleType:
    try:
        import huggingface_hub
    except ImportError:
        raise UserError("hf:// locations need huggingface_hub: pip install 'urdf-pipeline[hub]'") from None
    return huggingface_hub


def offline() -> bool:
    return os.environ.get(OFFLINE_ENV, "").strip().upper() in TRUE


def cache_dir() -> str | None:
    """The client's cache as the environment names it now; None: the client's default (~/.cache/huggingface/hub)."""
    chosen = os.environ.get("HF_HUB_CACHE")
    if chosen:
        return os.path.expanduser(os.path.expandvars(chosen))
    home = os.environ.get("HF_HOME")
    return os.path.join(os.path.expanduser(os.path.expandvars(home)), "hub") if home else None


def endpoint() -> str | None:
    return os.environ.get("HF_ENDPOINT", "").rstrip("/") or None


def _where_from() -> str:
    """Where a file would come from, for messages: the cache alone, or the endpoint (scheme and host only)."""
    if offline():
        return f"the local Hub cache ({shown(cache_dir() or 'the default, ~/.cache/huggingface/hub')}; {OFFLINE_ENV}=1)"
    return shown(endpoint() or "https://huggingface.co")


def _cached_refs(url: RemoteUrl) -> list[str]:
    """The branches and tags the local cache knows the commit of (refs/NAME files)."""
    from huggingface_hub import constants
    from huggingface_hub.file_download import repo_folder_name

    refs = Path(cache_dir() or constants.HF_HUB_CACHE) / repo_folder_name(repo_id=url.repo, repo_type="dataset") / "refs"
    try:
        return sorted(p.relative_to(refs).as_posix() for p in refs.rglob("*") if p.is_file())
    except OSError:
        return []


def hub_error(exc: BaseException, url: RemoteUrl, where: Where | None) -> UserError:
    """What went wrong with `url` in words that name the fix; the client's own text never (it may hold a request's
    headers), the HTTP status only."""
    from huggingface_hub import errors

    target, revision = shown(url.url, 200), shown(url.revision or "main")
    if isinstance(exc, errors.RevisionResolutionError | errors.OfflineModeIsEnabled):
        if offline():
            return UserError(
                f"cannot resolve revision {revision} of {target}: {_where_from()} holds no commit for it and the Hub is not "
                f"asked; the cache knows {listing(_cached_refs(url), empty='no revision of it')}: pin a commit it holds "
                f"(@REV or revision:), or run once with the Hub reachable",
                where,
            )
        return UserError(
            f"cannot resolve revision {revision} of {target}: {_where_from()} could not be reached and the local Hub cache "
            "holds no commit for it; check the network (or HF_ENDPOINT)",
            where,
        )
    if isinstance(exc, errors.RevisionNotFoundError):
        return UserError(f"{target}: the dataset has no revision {revision} (a branch, tag or commit) on {_where_from()}", where)
    if isinstance(exc, errors.GatedRepoError):
        return UserError(f"{target} is gated: accept its conditions on the Hub with the account of this run's token (HF_TOKEN)", where)
    if isinstance(exc, errors.RepositoryNotFoundError):
        return UserError(
            f"{target}: no such dataset on {_where_from()}, or it is private and this run's token may not read it "
            "(set HF_TOKEN, or run `hf auth login`)",
            where,
        )
    if isinstance(exc, errors.LocalEntryNotFoundError):
        if not offline():
            return UserError(
                f"{target} is not in the local Hub cache and cannot be downloaded from {_where_from()}: check the network", where
            )
        known = "" if url.key else f"; it knows the revisions {listing(_cached_refs(url), empty='none')}"
        cache = shown(cache_dir() or "the default, ~/.cache/huggingface/hub")
        return UserError(
            f"{target} is not in the local Hub cache ({cache}{known}), and {OFFLINE_ENV}=1 forbids downloading it: run once "
            "with the Hub reachable, or fill the cache",
            where,
        )
    if isinstance(exc, errors.EntryNotFoundError):
        return UserError(f"{target}: no such file in the dataset at commit {shown(url.revision)}", where)
    if isinstance(exc, errors.HfHubHTTPError):
        status = exc.response.status_code if exc.response is not None else "no answer"
        return UserError(f"cannot read {target}: HTTP {status} from {_where_from()}", where)
    return UserError(f"cannot read {target}: {shown(type(exc).__name__, 80)} ({shown(exc, 200)})", where)


def _errors() -> tuple[type[BaseException], ...]:
    import httpx2
    from huggingface_hub import errors

    return (
        errors.HfHubHTTPError,
        errors.RevisionResolutionError,
        errors.EntryNotFoundError,
        errors.OfflineModeIsEnabled,
        httpx2.HTTPError,
        OSError,
    )


@contextmanager
def _asking(url: RemoteUrl, where: Where | None) -> Iterator[ModuleType]:
    """The client, its progress bars off while it works (the run says what it does itself, one line per segment),
    and what goes wrong as `hub_error` says it."""
    hub = _client()
    from huggingface_hub.utils import disable_progress_bars

    try:
        with disable_progress_bars("huggingface_hub"):
            yield hub
    except _errors() as exc:
        raise hub_error(exc, url, where) from None


def hub_commit(url: RemoteUrl, where: Where | None) -> str:
    """The commit sha the dataset's revision (its default branch when unpinned) is at now; offline, the commit the
    cache last saw it at (refs/)."""
    with _asking(url, where) as hub:
        api = hub.HfApi(endpoint=endpoint())
        resolved = api.resolve_revision(
            url.repo, repo_type="dataset", revision=url.revision or None, cache_dir=cache_dir(), local_files_only=offline()
        )
    sha = str(resolved.resolved).strip()
    if not COMMIT.match(sha):
        raise UserError(f"{shown(url.url)}: the Hub cache says its revision is at {shown(sha, 60)}, which is no commit sha", where)
    return sha


def hub_snapshot(url: RemoteUrl, patterns: Sequence[str], where: Where | None) -> Path:
    """The dataset at `url`'s commit with the files matching `patterns` (`fnmatch`, on paths inside the repository)
    downloaded into the client's cache (nothing when they are there), and its snapshot folder: the dataset's files at
    their paths, links into the cache's blobs. Offline, the snapshot the cache holds."""
    assert COMMIT.match(url.revision), "a snapshot is taken at a commit (hub_commit first)"
    with _asking(url, where) as hub:
        folder = hub.snapshot_download(
            url.repo,
            repo_type="dataset",
            revision=url.revision,
            cache_dir=cache_dir(),
            local_files_only=offline(),
            allow_patterns=list(patterns),
            endpoint=endpoint(),
        )
    return Path(folder)


def hub_file(remote: RemoteObject, where: Where | None) -> Path:
    """One file of a dataset at the commit it was planned at, in the client's cache (downloaded unless it is there:
    a cached file at a commit costs no request)."""
    url = parse_url(remote.url, where)
    options: dict[str, Any] = {"cache_dir": cache_dir(), "local_files_only": offline(), "endpoint": endpoint()}
    with _asking(url, where) as hub:
        path = hub.hf_hub_download(url.repo, url.key, repo_type="dataset", revision=remote.version, **options)
    return Path(path)


def hub_files(url: RemoteUrl, snapshot: Path, under: str) -> list[RemoteObject]:
    """The files the snapshot folder of `url`'s commit holds under the folder `under` (a path inside the repository),
    as objects pinned to that commit, by path: what `hub_snapshot` fetched, or what the cache held offline."""
    assert COMMIT.match(url.revision), "files are listed at a commit (hub_commit first)"
    base = snapshot / under
    if not base.is_dir():
        return []
    found = []
    for path in sorted(p for p in base.rglob("*") if p.is_file()):  # one iteration per cached file of the folder
        inside = path.relative_to(snapshot).as_posix()
        found.append(RemoteObject(f"hf://datasets/{url.repo}@{url.revision}/{inside}", url.revision, path.stat().st_size))
    return found

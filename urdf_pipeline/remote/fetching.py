"""A config's remote file, from its URL to a local file Rerun's readers open: `remote_file` (parsed, allowed, and what
it is now: one HEAD), `cached_path` (where this machine's download cache keeps it) and `fetched` (downloaded once into
the cache, pinned to the version that was planned, and held while a segment reads it)."""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import UserError, Where, shown
from ..plan import RemoteObject
from .download_cache import CacheKey, DownloadCache
from .hub import hub_file
from .locations import remote_location
from .s3_objects import download, head, listing

_LISTED: dict[str, RemoteObject] = {}  # objects a glob listed in this process: what they are, without a HEAD each
GLOB_CHARACTERS = re.compile(r"[*?\[]")


def remote_glob(text: str, where: Where | None, what: str) -> list[RemoteObject]:
    """The objects an `s3://BUCKET/PREFIX/*.parquet` pattern matches, in key order: one listing of the prefix before
    the first glob character (`*` and `?` within a name, `**/` any folders deep, `[...]` a set)."""
    url = remote_location(text, where, what)
    if url.scheme != "s3":
        raise UserError(f"{what} {shown(url.url)}: a glob lists an S3 prefix (s3://BUCKET/PREFIX/*.parquet)", where)
    fixed = GLOB_CHARACTERS.split(url.key, 1)[0].rsplit("/", 1)[0]
    pattern = _glob_pattern(url.key)
    found = [o for o in listing(url.child_prefix(fixed), where) if pattern.fullmatch(o.url.split("/", 3)[3])]
    _LISTED.update((o.url, o) for o in found)
    return found


def _glob_pattern(key: str) -> re.Pattern[str]:
    parts = []
    for piece in re.split(r"(\*\*/|\*|\?|\[[^\]]*\])", key):
        if piece == "**/":
            parts.append("(?:[^/]+/)*")
        elif piece == "*":
            parts.append("[^/]*")
        elif piece == "?":
            parts.append("[^/]")
        elif piece.startswith("[") and piece.endswith("]") and len(piece) > 2:
            parts.append("[" + ("^" + re.escape(piece[2:-1]) if piece[1] == "!" else re.escape(piece[1:-1])) + "]")
        else:
            parts.append(re.escape(piece))
    return re.compile("".join(parts))


def remote_file(text: str, where: Where | None, what: str) -> RemoteObject:
    """The object a config names (`s3://BUCKET/KEY`), allowed by the environment, as it is now (as a glob of this
    process listed it, else one HEAD request)."""
    url = remote_location(text, where, what)
    if url.url in _LISTED:
        return _LISTED[url.url]
    if url.scheme != "s3":
        raise UserError(
            f"{what} {shown(url.url)}: a Hub dataset is read as a LeRobot source (lerobot: hf://datasets/ORG/NAME@REV); a single file is s3://BUCKET/KEY",
            where,
        )
    if not url.key or url.key.endswith("/"):
        raise UserError(f"{what} {shown(url.url)} names a prefix, not an object; name the file (s3://BUCKET/KEY)", where)
    return head(url, where)


def cache_key(remote: RemoteObject) -> CacheKey:
    return CacheKey(remote.url, remote.version, remote.url.rsplit("/", 1)[-1])


def download_folder() -> Path:
    """This machine's download cache (its folder), where the files of remote sources are kept."""
    return DownloadCache.from_environment().root


def cached_path(remote: RemoteObject) -> Path:
    """Where this machine's download cache keeps the object's planned version (it may not be there yet)."""
    return DownloadCache.from_environment().path(cache_key(remote))


@contextmanager
def fetched(remote: RemoteObject, where: Where | None) -> Iterator[Path]:
    """The object's planned version as a local file, downloaded into the cache unless it is there already, and kept
    from eviction while the block runs. A changed object is a UserError (its ETag is not the planned one). A Hub file
    is the Hub client's cached file at the planned commit (docs/remote.md says why it stays in that cache)."""
    if remote.url.startswith("hf://"):
        yield hub_file(remote, where)
        return
    with DownloadCache.from_environment().fetched(cache_key(remote), lambda target: download(remote, target, where)) as path:
        yield path


@contextmanager
def cached_metadata(remote: RemoteObject, what: str, write: Callable[[Path], None]) -> Iterator[Path]:
    """A file of the object's metadata (`what`: e.g. its parquet footer), made once per version by `write(target)`
    (a few ranged GETs) and kept in the download cache: a re-run with the ETag unchanged reads no byte of the object."""
    name = f"{remote.url.rsplit('/', 1)[-1]}.{what}"
    with DownloadCache.from_environment().fetched(CacheKey(remote.url, f"{remote.version}#{what}", name), write) as path:
        yield path

"""A local, content-addressed cache of downloaded objects (docs/remote.md: its purpose, variables and bound). Several
processes share one cache, so everything goes through `flock` locks and atomic renames, never through what a process
remembers:

    ROOT/.bytes           the ledger: the complete entries' bytes, as last counted (flocked while read or written)
    ROOT/ab/abcd.../      one entry, the sha256 of (url, version, name)
        NAME              the object, present only once whole: downloaded to `.partial-*`, fsynced, renamed to NAME
        .use.lock         shared-locked while the entry is in use or being fetched; its mtime is the entry's last use
        .fetch.lock       exclusive while one process downloads the entry (the others wait, then read what it wrote)
        .partial-*        a download under way, or a killed one's leftover (the next fetch of the entry removes it)

Eviction walks the tree once, then removes least recently used entries down to LOW_WATER of the bound, each only
under a non-blocking exclusive lock (one in use or being downloaded is skipped) and renamed aside first, so that no
process ever reads half of a removed entry.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import os
import re
import secrets
import shutil
import stat
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..errors import UserError, shown

CACHE_ENV = "URDF_PIPELINE_CACHE"
CACHE_BYTES_ENV = "URDF_PIPELINE_CACHE_BYTES"
DEFAULT_BYTES = 20 * 1024**3
LOW_WATER = 0.9  # eviction goes down to this share of the bound, so that a full cache is not walked on every download
NAME_LIMIT = 120  # characters of a cached file's name (a longer one keeps its head and its suffix)
SUFFIX_LIMIT = 24  # characters of a suffix kept when a name is shortened (`.parquet`, `.mcap`, `.hdf5`)
USE_LOCK = ".use.lock"
FETCH_LOCK = ".fetch.lock"
PARTIAL = ".partial-"
EVICTED = ".evicted-"
LEDGER = ".bytes"
LOCK_ATTEMPTS = 1000  # an entry removed under a process that was about to lock it: it tries again, boundedly
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]")  # everything else in a name (separators, controls, spaces, non-ASCII) -> "_"
_SIZE = re.compile(r"^([0-9]{1,20})([KMGT]?)$", re.IGNORECASE)  # ASCII digits (\d takes any script's)
_UNITS = {"": 1, "K": 1024, "M": 1024**2, "G": 1024**3, "T": 1024**4}
_SHARD = re.compile(r"^[0-9a-f]{2}$")
_ENTRY = re.compile(r"^[0-9a-f]{64}$")
_OPEN_FLAGS = os.O_CLOEXEC | os.O_NOFOLLOW  # a lock file planted as a symlink is refused, never followed


def safe_name(name: str) -> str:
    """`name` as a file name that stays in its entry's folder: its last path segment, every character but
    `A-Za-z0-9._+-` as `_`, no leading dot (the cache's own files start with one), at most NAME_LIMIT characters with
    its suffix kept (the readers choose by it); `object` when nothing is left."""
    segments = [segment for segment in re.split(r"[/\\]", name) if segment]
    cleaned = _UNSAFE.sub("_", segments[-1]) if segments else ""
    if not cleaned.strip("._"):  # "", ".", "..", "_": nothing of a name left
        cleaned = "object"
    if cleaned.startswith("."):
        cleaned = "_" + cleaned
    if len(cleaned) > NAME_LIMIT:
        dot = cleaned.rfind(".")
        suffix = cleaned[dot:] if 0 < dot and len(cleaned) - dot <= SUFFIX_LIMIT else ""
        cleaned = cleaned[: NAME_LIMIT - len(suffix)] + suffix
    return cleaned


@dataclass(frozen=True)
class CacheKey:
    """What an entry holds: the object at `url` as `version` says it is (its ETag, VersionId or Hub commit sha; a new
    version is a new entry), kept under its own `name` (made safe: `file_name`)."""

    url: str  # the remote location as text (s3://bucket/key)
    version: str
    name: str

    def __post_init__(self) -> None:
        if not self.url or not self.version:
            raise ValueError(f"a cache key needs a url and a version: {self!r}")

    @property
    def digest(self) -> str:
        """sha256 of the three fields, each length-prefixed (no two keys run together into one)."""
        digest = hashlib.sha256()
        for part in (self.url, self.version, self.name):
            data = part.encode("utf-8", "surrogatepass")
            digest.update(len(data).to_bytes(8, "big") + data)
        return digest.hexdigest()

    @property
    def file_name(self) -> str:
        return safe_name(self.name)


def parse_bytes(text: str, variable: str = CACHE_BYTES_ENV) -> int:
    """A size as the environment writes it: bytes, or a number with K, M, G or T (powers of 1024), e.g. `20G`."""
    match = _SIZE.match(text.strip())
    if not match:
        raise UserError(
            f"{variable}={shown(text, 40)} is not a size: write a whole number of bytes, or one with K, M, G or T "
            f"(powers of 1024), e.g. {variable}=20G"
        )
    return int(match.group(1)) * _UNITS[match.group(2).upper()]


def default_root() -> Path:
    """`$URDF_PIPELINE_CACHE`, else `$XDG_CACHE_HOME/urdf-pipeline/downloads`, else `~/.cache/urdf-pipeline/downloads`
    (a relative XDG_CACHE_HOME is ignored, as its specification says)."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen:
        return Path(chosen).expanduser().absolute()
    base = os.environ.get("XDG_CACHE_HOME", "")
    cache = Path(base) if os.path.isabs(base) else Path.home() / ".cache"
    return cache / "urdf-pipeline" / "downloads"


class DownloadCache:
    """Objects downloaded once into `root`, kept while the cache holds at most `max_bytes` of them (least recently
    used first out). An object bigger than the bound alone is still fetched and kept while in use; a later download
    evicts it."""

    def __init__(self, root: Path, max_bytes: int) -> None:
        if max_bytes < 0:
            raise ValueError(f"max_bytes must be 0 or more, not {max_bytes}")
        self.root = Path(root)
        self.max_bytes = max_bytes

    @classmethod
    def from_environment(cls) -> DownloadCache:
        """The cache the environment names (CACHE_ENV, CACHE_BYTES_ENV; 20G by default)."""
        text = os.environ.get(CACHE_BYTES_ENV, "").strip()
        return cls(default_root(), parse_bytes(text) if text else DEFAULT_BYTES)

    def folder(self, key: CacheKey) -> Path:
        digest = key.digest
        return self.root / digest[:2] / digest

    def path(self, key: CacheKey) -> Path:
        """Where the entry's file is once complete (it may not be yet: `contains`)."""
        return self.folder(key) / key.file_name

    def contains(self, key: CacheKey) -> bool:
        """The entry is complete (a download under way or one that failed never counts)."""
        return _is_file(self.path(key))

    @contextmanager
    def fetched(self, key: CacheKey, download: Callable[[Path], None]) -> Iterator[Path]:
        """The entry's file, downloaded once: `download(temp)` writes the whole object to `temp` (in the cache's own
        folder) and checks it is whole; an exception leaves no entry. The entry is never evicted while the block runs."""
        self._make_root()
        folder = self.folder(key)
        target = folder / key.file_name
        use = _lock_entry(folder)
        try:
            if not _is_file(target) and self._download(key, folder, target, download):
                self._evict_if_over(keep=folder)
            now = time.time_ns()
            os.utime(use, ns=(now, now))  # the last use, on the lock file: the object's own mtime stays its download's
            yield target
        finally:
            os.close(use)  # releases the shared lock

    def _make_root(self) -> None:
        try:
            self.root.mkdir(mode=0o700, parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(
                f"cannot create the download cache {shown(str(self.root))}: {exc.strerror or exc}; set {CACHE_ENV} to a writable folder"
            ) from None

    def _download(self, key: CacheKey, folder: Path, target: Path, download: Callable[[Path], None]) -> bool:
        """The object into `target`, unless another process did it while this one waited: True when this one did."""
        with _flocked(folder / FETCH_LOCK, fcntl.LOCK_EX):
            if _is_file(target):
                return False
            _remove_partials(folder)  # whoever wrote them died: only the holder of the fetch lock writes one
            handle, name = tempfile.mkstemp(prefix=PARTIAL, dir=folder)
            os.close(handle)
            temp = Path(name)
            try:
                download(temp)
                size = _synced_size(temp)
                temp.chmod(0o444)
                with _flocked(self.root / LEDGER, fcntl.LOCK_EX) as ledger:  # counted and renamed as one step
                    total = _read_ledger(ledger)
                    if total is not None:
                        _write_ledger(ledger, total + size)
                    os.replace(temp, target)
            except BaseException as exc:
                _remove_partials(folder)
                if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
                    raise self._no_space(key) from None
                raise
            _fsync_folder(folder)
        return True

    def _no_space(self, key: CacheKey) -> UserError:
        return UserError(
            f"no space left to download {shown(key.url)} into the download cache {shown(str(self.root))}: free some, "
            f"lower {CACHE_BYTES_ENV} (now {self.max_bytes} bytes) or set {CACHE_ENV} to a folder on a larger disk"
        )

    def _evict_if_over(self, keep: Path) -> None:
        """After a download: when the ledger is over the bound (or unreadable), walk the cache, count it and evict.
        The evicted entries are only renamed aside under the ledger's lock, and deleted after it (other processes
        wait for that lock to finish their downloads)."""
        with _flocked(self.root / LEDGER, fcntl.LOCK_EX) as ledger:
            total = _read_ledger(ledger)
            if total is not None and total <= self.max_bytes:
                return
            total, evicted = self._evict(keep)
            _write_ledger(ledger, total)
        for aside in evicted:
            shutil.rmtree(aside, ignore_errors=True)

    def _evict(self, keep: Path) -> tuple[int, list[Path]]:
        """Least recently used complete entries set aside until the cache holds at most LOW_WATER of the bound, never
        `keep` nor one in use: the bytes left, and the folders set aside."""
        entries, total = self._scan()
        evicted: list[Path] = []
        goal = int(self.max_bytes * LOW_WATER) if total > self.max_bytes else total
        for _, _, folder, size in sorted(entries):
            if total <= goal:
                break
            aside = _set_aside(folder) if folder != keep else None
            if aside is not None:
                evicted.append(aside)
                total -= size
        return total, evicted

    def _scan(self) -> tuple[list[tuple[int, str, Path, int]], int]:
        """Every complete entry as (last use, name, folder, bytes), and their bytes together; on the way, what a
        killed process left (an evicted entry half removed, an incomplete entry no one holds) is removed."""
        entries: list[tuple[int, str, Path, int]] = []
        total = 0
        with os.scandir(self.root) as items:  # a symlink or a stranger's file is never a shard
            shards = [Path(item.path) for item in items if _SHARD.match(item.name) and item.is_dir(follow_symlinks=False)]
        for shard in shards:
            with os.scandir(shard) as items:
                listed = list(items)
            for item in listed:
                if item.name.startswith(EVICTED):
                    shutil.rmtree(item.path, ignore_errors=True)  # evicted; its evictor may be removing it too
                    continue
                if not (_ENTRY.match(item.name) and item.is_dir(follow_symlinks=False)):
                    continue
                state = _entry_state(Path(item.path))
                if state is None:
                    continue  # no lock file yet: a process is creating it
                used, size = state
                if size is None:
                    _remove(_set_aside(Path(item.path)))  # incomplete: skipped if a download holds it
                    continue
                entries.append((used, item.name, Path(item.path), size))
                total += size
        return entries, total


def _entry_state(folder: Path) -> tuple[int, int | None] | None:
    """(last use, the object's bytes or None when incomplete), or None when the entry has no lock file yet."""
    used: int | None = None
    size: int | None = None
    try:
        with os.scandir(folder) as items:
            for item in items:
                if item.name == USE_LOCK:
                    used = item.stat(follow_symlinks=False).st_mtime_ns
                elif not item.name.startswith(".") and item.is_file(follow_symlinks=False):
                    size = item.stat(follow_symlinks=False).st_size
    except FileNotFoundError:
        return None  # evicted while this walk looked at it
    return None if used is None else (used, size)


def _is_file(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _same_file(handle: int, path: Path) -> bool:
    """The open lock file is still the one at `path` (not one an evictor renamed away with its folder)."""
    try:
        named = os.lstat(path)
    except FileNotFoundError:
        return False
    opened = os.fstat(handle)
    return (named.st_dev, named.st_ino) == (opened.st_dev, opened.st_ino)


def _lock_entry(folder: Path) -> int:
    """The entry's use lock, held shared: open, locked, and still the live one. An evictor may remove the folder
    between any two steps; then the next attempt makes it again."""
    for _ in range(LOCK_ATTEMPTS):
        folder.parent.mkdir(mode=0o700, exist_ok=True)
        folder.mkdir(mode=0o700, exist_ok=True)
        try:
            handle = os.open(folder / USE_LOCK, os.O_RDWR | os.O_CREAT | _OPEN_FLAGS, 0o600)
        except FileNotFoundError:
            continue
        try:
            fcntl.flock(handle, fcntl.LOCK_SH)
            if _same_file(handle, folder / USE_LOCK):
                return handle
        except BaseException:
            os.close(handle)
            raise
        os.close(handle)
    raise RuntimeError(f"the cache entry {folder} was removed {LOCK_ATTEMPTS} times while this process locked it")


@contextmanager
def _flocked(path: Path, operation: int) -> Iterator[int]:
    """A lock file of the cache's own, never removed while in use (the ledger; a fetch lock, inside a used entry)."""
    handle = os.open(path, os.O_RDWR | os.O_CREAT | _OPEN_FLAGS, 0o600)
    try:
        fcntl.flock(handle, operation)
        yield handle
    finally:
        os.close(handle)


def _set_aside(folder: Path) -> Path | None:
    """The entry renamed aside (to be deleted) if no one uses or downloads it, under its exclusive lock: no process
    can lock it any more, nor read a half-removed file. None when it is in use."""
    try:
        handle = os.open(folder / USE_LOCK, os.O_RDWR | _OPEN_FLAGS)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return None
        if not _same_file(handle, folder / USE_LOCK):
            return None
        aside = folder.with_name(f"{EVICTED}{folder.name}-{secrets.token_hex(4)}")
        os.rename(folder, aside)
        return aside
    finally:
        os.close(handle)


def _remove(aside: Path | None) -> None:
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)


def _remove_partials(folder: Path) -> None:
    with os.scandir(folder) as items:
        for item in items:
            if item.name.startswith(PARTIAL):
                Path(item.path).unlink(missing_ok=True)


def _synced_size(path: Path) -> int:
    """The downloaded file's bytes, on disk before it is renamed into place (a crash never leaves a short entry)."""
    handle = os.open(path, os.O_RDONLY | _OPEN_FLAGS)
    try:
        status = os.fstat(handle)
        if not stat.S_ISREG(status.st_mode):
            raise RuntimeError(f"the download into {path} left no regular file")
        os.fsync(handle)
        return status.st_size
    finally:
        os.close(handle)


def _fsync_folder(folder: Path) -> None:
    handle = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


def _read_ledger(handle: int) -> int | None:
    """The ledger's count; None when it is missing or damaged (a crash while it was written): the cache is walked."""
    text = os.pread(handle, 64, 0).decode("ascii", "replace")
    return int(text[:-1]) if text.endswith("\n") and text[:-1].isdigit() else None


def _write_ledger(handle: int, total: int) -> None:
    os.ftruncate(handle, 0)
    os.pwrite(handle, f"{total}\n".encode("ascii"), 0)

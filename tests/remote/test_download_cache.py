"""The download cache with real processes sharing one folder: a download happens once however many processes want
it, a failed or killed download never counts, eviction is least recently used and never takes an entry in use, and a
name from a URL never leads out of the cache."""

from __future__ import annotations

import errno
import hashlib
import multiprocessing
import os
import signal
import stat
import time
from collections.abc import Callable, Iterator
from multiprocessing.process import BaseProcess
from pathlib import Path

import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.remote import CACHE_BYTES_ENV, CACHE_ENV, CacheKey, DownloadCache
from urdf_pipeline.remote.download_cache import DEFAULT_BYTES, LEDGER, NAME_LIMIT, PARTIAL, default_root, safe_name

SPAWN = multiprocessing.get_context("spawn")
PATIENCE = 120.0  # seconds before a wait for another process gives up: a hang fails, never a slow machine


def _wait_for(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + PATIENCE
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"no {what} after {PATIENCE:.0f} s")
        time.sleep(0.01)


def _content(key: CacheKey, size: int = 300) -> bytes:
    return (hashlib.sha256(f"{key.url}@{key.version}".encode()).hexdigest().encode() * (size // 64 + 1))[:size]


def _counting(key: CacheKey, calls: Path, size: int = 300) -> Callable[[Path], None]:
    """A download that writes the object and appends a line to `calls`."""

    def download(temp: Path) -> None:
        with calls.open("a") as log:
            log.write(f"{os.getpid()}\n")
        temp.write_bytes(_content(key, size))

    return download


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def _key(name: str, version: str = '"etag-1"') -> CacheKey:
    return CacheKey(f"s3://robot-data/so101/{name}", version, name)


def _fetch(cache: DownloadCache, key: CacheKey, calls: Path, size: int = 300) -> bytes:
    with cache.fetched(key, _counting(key, calls, size)) as path:
        return path.read_bytes()


# ---- what the child processes run (top-level functions: the spawn context imports this module) ----


def _fetch_when_released(root: str, name: str, calls: str, release: str, ready: str, result: str) -> None:
    """Fetch `name`; the download, if this process does it, writes half, then waits for `release`."""
    key = _key(name)

    def download(temp: Path) -> None:
        with open(calls, "a") as log:
            log.write(f"{os.getpid()}\n")
        data = _content(key)
        with temp.open("wb") as out:
            out.write(data[:100])
            out.flush()
            while not os.path.exists(release):
                time.sleep(0.01)
            out.write(data[100:])

    Path(ready + ".tmp").write_text(f"{os.getpid()}\n")
    os.replace(ready + ".tmp", ready)  # whole when it appears
    with DownloadCache(Path(root), 10**9).fetched(key, download) as path:
        Path(result).write_bytes(path.read_bytes())


def _download_until_killed(root: str, name: str, started: str) -> None:
    """Writes part of the object, and a second temporary file beside it as boto3 does, then waits to be killed."""

    def download(temp: Path) -> None:
        temp.write_bytes(b"half an object")
        temp.with_name(temp.name + ".a1B2c3").write_bytes(b"boto3's own partial file")
        Path(started).write_text("downloading")
        while True:
            time.sleep(1)

    with DownloadCache(Path(root), 10**9).fetched(_key(name), download):
        raise AssertionError("a killed download finished")


def _hold(root: str, name: str, calls: str, holding: str, release: str) -> None:
    """Fetch `name` and keep it in use until `release` exists."""
    key = _key(name)
    with DownloadCache(Path(root), 10**9).fetched(key, _counting(key, Path(calls))) as path:
        Path(holding).write_text(str(path))
        while not os.path.exists(release):
            time.sleep(0.01)
        assert path.read_bytes() == _content(key)


@pytest.fixture
def start() -> Iterator[Callable[..., BaseProcess]]:
    """Starts a child process running a function of this module; a child a failed test leaves waiting is killed."""
    started: list[BaseProcess] = []

    def start_child(target: Callable[..., None], *args: object) -> BaseProcess:
        process = SPAWN.Process(target=target, args=args)
        process.start()
        started.append(process)
        return process

    yield start_child
    for process in started:
        if process.is_alive():
            process.kill()
        process.join()


def _blocked_on_a_lock(pid: int) -> bool:
    """/proc/locks lists a process waiting for a flock as `N: -> FLOCK ADVISORY WRITE PID ...`."""
    return any(line.split()[1:2] == ["->"] and str(pid) in line.split() for line in Path("/proc/locks").read_text().splitlines())


# ---- tests ----


def test_two_processes_fetching_one_object_download_it_once(tmp_path: Path, start: Callable[..., BaseProcess]) -> None:
    root, calls, release = tmp_path / "cache", tmp_path / "calls", tmp_path / "release"
    first = start(_fetch_when_released, str(root), "a.parquet", str(calls), str(release), str(tmp_path / "r1"), str(tmp_path / "o1"))
    _wait_for(lambda: len(_lines(calls)) == 1, "download started in the first process")
    second = start(_fetch_when_released, str(root), "a.parquet", str(calls), str(release), str(tmp_path / "r2"), str(tmp_path / "o2"))
    _wait_for(lambda: (tmp_path / "r2").exists(), "fetch started in the second process")
    if Path("/proc/locks").exists():  # the second is waiting for the first's download, not merely late
        _wait_for(lambda: _blocked_on_a_lock(int((tmp_path / "r2").read_text())), "second process waiting on the fetch lock")
    assert not DownloadCache(root, 10**9).contains(_key("a.parquet")), "half a download counts"
    release.touch()
    first.join(PATIENCE)
    second.join(PATIENCE)
    assert (first.exitcode, second.exitcode) == (0, 0)
    assert len(_lines(calls)) == 1
    expected = _content(_key("a.parquet"))
    assert (tmp_path / "o1").read_bytes() == expected and (tmp_path / "o2").read_bytes() == expected


def test_a_fetched_object_is_read_again_without_a_download_and_a_new_version_is_a_new_entry(tmp_path: Path) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 10**9), tmp_path / "calls"
    key = _key("episode_000000.parquet")
    assert _fetch(cache, key, calls) == _fetch(cache, key, calls) == _content(key)
    assert len(_lines(calls)) == 1
    digest = hashlib.sha256()
    for part in (key.url, key.version, key.name):
        digest.update(len(part.encode()).to_bytes(8, "big") + part.encode())
    assert cache.path(key) == tmp_path / "cache" / digest.hexdigest()[:2] / digest.hexdigest() / "episode_000000.parquet"
    assert stat.S_IMODE(cache.path(key).stat().st_mode) == 0o444, "a cached object is read-only"
    changed = _key("episode_000000.parquet", '"etag-2"')
    assert _fetch(cache, changed, calls) == _content(changed) != _content(key)
    assert len(_lines(calls)) == 2
    assert cache.contains(key) and cache.contains(changed)
    assert stat.S_IMODE((tmp_path / "cache").stat().st_mode) == 0o700


def test_a_download_that_raises_leaves_no_entry_and_the_next_fetch_downloads(tmp_path: Path) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 10**9), tmp_path / "calls"
    key = _key("a.mcap")

    def failing(temp: Path) -> None:
        temp.write_bytes(b"the first bytes")
        temp.with_name(temp.name + ".part").write_bytes(b"more")
        raise ConnectionError("the server went away")

    with pytest.raises(ConnectionError), cache.fetched(key, failing):
        raise AssertionError("a failed download was used")
    assert not cache.contains(key)
    assert not [p.name for p in cache.folder(key).iterdir() if p.name.startswith(PARTIAL)]
    assert _fetch(cache, key, calls) == _content(key)
    assert len(_lines(calls)) == 1


def test_a_full_disk_is_a_user_error_that_says_what_to_change(tmp_path: Path) -> None:
    cache, key = DownloadCache(tmp_path / "cache", 10**9), _key("a.parquet")

    def full(temp: Path) -> None:
        temp.write_bytes(b"the first bytes")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(temp))

    with pytest.raises(UserError, match=f"no space left to download s3://robot-data/so101/a.parquet .*{CACHE_BYTES_ENV}"):
        with cache.fetched(key, full):
            raise AssertionError("a failed download was used")
    assert not cache.contains(key)
    assert not [p.name for p in cache.folder(key).iterdir() if p.name.startswith(PARTIAL)]


def test_a_download_killed_midway_is_not_used_and_its_leftovers_are_removed(tmp_path: Path, start: Callable[..., BaseProcess]) -> None:
    root, started, calls = tmp_path / "cache", tmp_path / "started", tmp_path / "calls"
    child = start(_download_until_killed, str(root), "b.parquet", str(started))
    _wait_for(started.exists, "download started in the child")
    assert child.pid is not None
    os.kill(child.pid, signal.SIGKILL)
    child.join(PATIENCE)
    assert child.exitcode == -signal.SIGKILL
    cache, key = DownloadCache(root, 10**9), _key("b.parquet")
    leftovers = sorted(p.name for p in cache.folder(key).iterdir() if p.name.startswith(PARTIAL))
    assert len(leftovers) == 2, "the killed download left its partial files"
    assert not cache.contains(key)
    assert _fetch(cache, key, calls) == _content(key)
    assert len(_lines(calls)) == 1
    assert sorted(p.name for p in cache.folder(key).iterdir() if not p.name.endswith(".lock")) == ["b.parquet"]


def test_eviction_removes_the_least_recently_used_entries(tmp_path: Path) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 1000), tmp_path / "calls"
    a, b, c, d, e = (_key(f"{n}.parquet") for n in "abcde")
    for key in (a, b, c):
        _fetch(cache, key, calls)
    _fetch(cache, a, calls)  # a used again: b is now the least recently used
    assert all(cache.contains(k) for k in (a, b, c))
    _fetch(cache, d, calls)  # 1200 bytes > 1000: down to at most 900
    assert [cache.contains(k) for k in (a, b, c, d)] == [True, False, True, True]
    _fetch(cache, e, calls)
    assert [cache.contains(k) for k in (a, c, d, e)] == [True, False, True, True]
    assert len(_lines(calls)) == 5
    assert (tmp_path / "cache" / LEDGER).read_text() == "900\n"
    assert not [p for p in (tmp_path / "cache").glob("*/.evicted-*")]


def test_an_entry_in_use_in_another_process_is_not_evicted(tmp_path: Path, start: Callable[..., BaseProcess]) -> None:
    root, calls, holding, release = tmp_path / "cache", tmp_path / "calls", tmp_path / "holding", tmp_path / "release"
    child = start(_hold, str(root), "held.parquet", str(calls), str(holding), str(release))
    _wait_for(holding.exists, "the child holding its entry")
    cache = DownloadCache(root, 1000)
    held, y, z, w, v = _key("held.parquet"), _key("y.parquet"), _key("z.parquet"), _key("w.parquet"), _key("v.parquet")
    for key in (y, z, w):  # the held entry is the least recently used, yet in use
        _fetch(cache, key, calls)
    assert [cache.contains(k) for k in (held, y, z, w)] == [True, False, True, True]
    release.touch()
    child.join(PATIENCE)
    assert child.exitcode == 0
    _fetch(cache, v, calls)  # no longer in use: the held entry goes first
    assert [cache.contains(k) for k in (held, z, w, v)] == [False, True, True, True]


def test_an_object_bigger_than_the_bound_is_fetched_and_evicted_by_a_later_download(tmp_path: Path) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 100), tmp_path / "calls"
    big, small = _key("big.rrd"), _key("small.csv")
    with cache.fetched(big, _counting(big, calls, 500)) as path:
        assert path.read_bytes() == _content(big, 500)
    assert cache.contains(big)
    assert _fetch(cache, small, calls, 10) == _content(small, 10)
    assert not cache.contains(big) and cache.contains(small)


def test_a_lost_or_damaged_ledger_is_counted_again(tmp_path: Path) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 10**6), tmp_path / "calls"
    _fetch(cache, _key("a.csv"), calls)
    ledger = tmp_path / "cache" / LEDGER
    ledger.write_text("30")  # no newline: a write cut short
    _fetch(cache, _key("b.csv"), calls)
    assert ledger.read_text() == "600\n"
    ledger.unlink()
    _fetch(cache, _key("c.csv"), calls)
    assert ledger.read_text() == "900\n"


HOSTILE_NAMES = [
    "../../../etc/passwd",
    "a/b/../../c.parquet",
    "..",
    ".",
    "",
    "/",
    ".use.lock",
    ".fetch.lock",
    ".partial-x",
    "..\\..\\windows.parquet",
    "line\nbreak\x00nul\x1b[31m.parquet",
    "\u202eevil\u2066.mcap",
    "épisode 0.hdf5",
    "x" * 5000 + ".parquet",
    "." * 300,
]


@pytest.mark.parametrize("name", HOSTILE_NAMES, ids=range(len(HOSTILE_NAMES)))
def test_a_hostile_name_stays_in_its_entry_and_keeps_its_suffix(tmp_path: Path, name: str) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 10**9), tmp_path / "calls"
    key = CacheKey(f"s3://robot-data/{name}", '"etag"', name)
    with cache.fetched(key, _counting(key, calls)) as path:
        assert path.parent == cache.folder(key) and path.resolve().parent == cache.folder(key).resolve()
        assert path.read_bytes() == _content(key)
    safe = path.name
    assert safe == safe_name(name) and 0 < len(safe) <= NAME_LIMIT
    assert not safe.startswith(".") and all(ch.isascii() and ch.isprintable() and ch not in "/\\" for ch in safe)
    for suffix in (".parquet", ".mcap", ".hdf5"):
        assert safe.endswith(suffix) == name.endswith(suffix)
    assert sorted(p.name for p in (tmp_path / "cache").rglob("*") if p.is_file() and not p.name.startswith(".")) == [safe]


def test_safe_names() -> None:
    assert safe_name("../../etc/passwd") == "passwd"
    assert safe_name("meta/episodes.jsonl") == "episodes.jsonl"
    assert safe_name(".use.lock") == "_.use.lock"
    assert safe_name("..") == safe_name("") == safe_name("/") == "object"
    assert safe_name("a b\x00.parquet") == "a_b_.parquet"
    long = safe_name("y" * 1000 + ".parquet")
    assert len(long) == NAME_LIMIT and long.endswith("y.parquet")


def test_a_symlink_planted_as_the_object_is_not_an_entry(tmp_path: Path) -> None:
    cache, calls = DownloadCache(tmp_path / "cache", 10**9), tmp_path / "calls"
    key = _key("a.parquet")
    secret = tmp_path / "secret"
    secret.write_text("not the object")
    cache.folder(key).mkdir(parents=True)
    cache.path(key).symlink_to(secret)
    assert not cache.contains(key)
    assert _fetch(cache, key, calls) == _content(key)
    assert secret.read_text() == "not the object" and not cache.path(key).is_symlink()


@pytest.mark.parametrize(
    ("text", "expected"),
    [("20G", 20 * 1024**3), ("512m", 512 * 1024**2), ("1024", 1024), (" 3K ", 3072), ("1T", 1024**4), ("0", 0)],
)
def test_the_bound_from_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, text: str, expected: int) -> None:
    monkeypatch.setenv(CACHE_BYTES_ENV, text)
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "mine"))
    cache = DownloadCache.from_environment()
    assert (cache.max_bytes, cache.root) == (expected, tmp_path / "mine")


@pytest.mark.parametrize("text", ["abc", "-1", "1.5G", "20GB", "1P", "G", "9" * 30, "1 0", "२०G"])
def test_a_bad_bound_is_a_user_error_naming_the_variable(monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    monkeypatch.setenv(CACHE_BYTES_ENV, text)
    with pytest.raises(UserError, match=f"{CACHE_BYTES_ENV}=.*is not a size.*K, M, G or T"):
        DownloadCache.from_environment()


def test_the_default_folder_and_bound(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for variable in (CACHE_ENV, CACHE_BYTES_ENV):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    cache = DownloadCache.from_environment()
    assert (cache.root, cache.max_bytes) == (tmp_path / "xdg" / "urdf-pipeline" / "downloads", DEFAULT_BYTES)
    monkeypatch.setenv("XDG_CACHE_HOME", "relative")
    assert default_root() == Path.home() / ".cache" / "urdf-pipeline" / "downloads"


def test_a_cache_folder_that_cannot_be_made_is_a_user_error(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    (tmp_path / "a-file").write_text("")
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "a-file" / "cache"))
    cache = DownloadCache.from_environment()
    with pytest.raises(UserError, match=CACHE_ENV), cache.fetched(_key("a.csv"), _counting(_key("a.csv"), tmp_path / "calls")):
        pass

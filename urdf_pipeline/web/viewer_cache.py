"""Rerun's web viewer of the pinned release, taken from the installed rerun-sdk's own `rerun` binary and kept in a
per-user cache, one folder per Rerun version.

A recording opens only in its own release's viewer, and the npm package stops at 0.33: the binary that ships in
rerun-sdk serves the matching `re_viewer.js` and `re_viewer_bg.wasm` (`rerun --serve-web`). It is started once per
Rerun version and machine, on 127.0.0.1 with ports the system picks, asked for the files, and stopped whatever
happens. It runs with `CI` set, Rerun's own switch that keeps its usage analytics off (it counts each wasm it serves).

The cache (`$URDF_PIPELINE_WEB_CACHE`, else `$XDG_CACHE_HOME/urdf-pipeline/web-viewer`, else
`~/.cache/urdf-pipeline/web-viewer`) holds `<version>/` once complete: it is built in a temporary folder beside it and
renamed into place, under a lock, so two processes never see half of it and fetch it once. Its files are read-only:
sites hard-link them.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from ..errors import UserError
from .binary_server import rerun_binary, serving_web_viewer

CACHE_VARIABLE = "URDF_PIPELINE_WEB_CACHE"
FILES = ("re_viewer.js", "re_viewer_bg.wasm", "favicon.ico")
WASM_MAGIC = b"\0asm"
INDEX = "viewer.json"  # written last: a folder without it is not a complete copy


@dataclass(frozen=True)
class ViewerAssets:
    """The pinned release's web viewer files in the cache: `folder / name` for each of `FILES`."""

    folder: Path
    rerun_version: str

    def path(self, name: str) -> Path:
        return self.folder / name

    @property
    def size(self) -> int:
        """Bytes of the viewer's files together (the wasm is about 43 MB)."""
        return sum((self.folder / name).stat().st_size for name in FILES)


def cache_root() -> Path:
    """Where the viewers of every Rerun version are kept (see the module's docstring)."""
    chosen = os.environ.get(CACHE_VARIABLE)
    if chosen:
        return Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "urdf-pipeline" / "web-viewer"


def rerun_version() -> str:
    """The installed rerun-sdk's version (what `rerun.__version__` says), from its metadata: no import of Rerun."""
    try:
        return version("rerun-sdk")
    except PackageNotFoundError:
        raise UserError("the web viewer comes from rerun-sdk, which is not installed: pip install 'rerun-sdk==0.41.*'") from None


def viewer_assets() -> ViewerAssets:
    """The pinned release's viewer, from the cache, fetched from the `rerun` binary the first time."""
    wanted = rerun_version()
    root = cache_root()
    folder = root / wanted
    if _complete(folder, wanted):
        return ViewerAssets(folder, wanted)
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(
            f"cannot create the web viewer cache {root}: {exc.strerror or exc}; set {CACHE_VARIABLE} to a writable folder"
        ) from None
    with _locked(root / f".{wanted}.lock"):
        if not _complete(folder, wanted):  # another process may have fetched it while this one waited
            _replace_broken(folder)
            _fetch_into(folder, wanted)
    return ViewerAssets(folder, wanted)


def _complete(folder: Path, wanted: str) -> bool:
    """A finished copy of `wanted`'s viewer: its index names the version, and every file has the size it lists."""
    try:
        index = json.loads((folder / INDEX).read_text(encoding="utf-8"))
        sizes = index["files"]
        if index.get("rerun") != wanted or set(sizes) != set(FILES):
            return False
        if any((folder / name).stat().st_size != sizes[name] for name in FILES):
            return False
        with open(folder / "re_viewer_bg.wasm", "rb") as wasm:
            return wasm.read(4) == WASM_MAGIC
    except (OSError, ValueError, KeyError, TypeError):
        return False


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """One process at a time fetches a version (the others wait, then find it complete)."""
    with open(path, "a+b") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _replace_broken(folder: Path) -> None:
    """An incomplete or damaged copy (a file removed by hand, a disk that filled) is moved aside and removed."""
    if folder.exists() or folder.is_symlink():
        aside = folder.with_name(f".{folder.name}.broken-{os.getpid()}")
        os.replace(folder, aside)
        _remove(aside)


def _remove(path: Path) -> None:
    """A cache folder removed, read-only files included (their folder's write permission is what unlinking needs)."""
    if path.is_dir() and not path.is_symlink():
        path.chmod(0o755)
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def _fetch_into(folder: Path, wanted: str) -> None:
    """The viewer's files from the binary into a temporary folder beside `folder`, checked, then renamed to it."""
    binary = rerun_binary(wanted)
    partial = Path(tempfile.mkdtemp(prefix=f".{folder.name}.partial-", dir=folder.parent))
    try:
        with serving_web_viewer(binary, partial) as port:
            sizes = {name: _download(f"http://127.0.0.1:{port}/{name}", partial / name) for name in FILES}
        _check(partial, wanted)
        (partial / INDEX).write_text(json.dumps({"rerun": wanted, "binary": binary, "files": sizes, "fetched": time.time()}, indent=1))
        for name in (*FILES, INDEX):
            (partial / name).chmod(0o444)
        (partial / "rerun.log").unlink(missing_ok=True)
        partial.chmod(0o755)
        os.rename(partial, folder)
    finally:
        if partial.exists():
            _remove(partial)


def _download(url: str, path: Path) -> int:
    """One file from the local server, streamed to `path` (no proxy: the server is on this machine)."""
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
    try:
        with opener.open(url, timeout=120) as response, open(path, "wb") as out:
            shutil.copyfileobj(response, out, 1 << 20)
    except (urllib.error.URLError, OSError) as exc:
        raise UserError(f"cannot take the web viewer from the rerun binary ({url}): {exc}") from None
    return path.stat().st_size


def _check(folder: Path, wanted: str) -> None:
    """What was served is a viewer: a WebAssembly module and the JavaScript that starts it."""
    with open(folder / "re_viewer_bg.wasm", "rb") as wasm:
        if wasm.read(4) != WASM_MAGIC:
            raise UserError(f"the rerun binary of rerun-sdk {wanted} served no WebAssembly as re_viewer_bg.wasm; reinstall rerun-sdk")
    script = (folder / "re_viewer.js").read_text(encoding="utf-8", errors="replace")
    if "wasm_bindgen" not in script or "WebHandle" not in script:
        raise UserError(f"the rerun binary of rerun-sdk {wanted} served an unexpected re_viewer.js; reinstall rerun-sdk")

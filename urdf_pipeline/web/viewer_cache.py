"""Rerun's web viewer of the pinned release, taken from the installed rerun-sdk's own `rerun` binary and kept in a
per-user cache, one folder per Rerun version.

A recording opens only in its own release's viewer, and the npm package stops at 0.33: the binary that ships in
rerun-sdk serves the matching `re_viewer.js` and `re_viewer_bg.wasm` (`rerun --serve-web`). It is started once per
Rerun version and machine, on 127.0.0.1 with ports the system picks, asked for the files, and stopped whatever
happens: in a session of its own (Ctrl-C in the terminal reaches us, not it), dying with us on Linux, telling its port
in its log. It runs with `CI` set, Rerun's own switch that keeps its usage analytics off (it counts each wasm it serves).

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
import re
import shutil
import subprocess
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from ..errors import UserError
from ..process import start_viewer, stop_session, viewer_binary

CACHE_VARIABLE = "URDF_PIPELINE_WEB_CACHE"
FILES = ("re_viewer.js", "re_viewer_bg.wasm", "favicon.ico")
WASM_MAGIC = b"\0asm"
INDEX = "viewer.json"  # written last: a folder without it is not a complete copy
STARTUP_SECONDS = 30.0  # for the binary to say the port it serves the web viewer on
HOSTING = re.compile(r"Hosting a web-viewer at http://127\.0\.0\.1:(\d+)")


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


def rerun_binary(wanted: str) -> str:
    """The viewer binary of rerun-sdk (`process.viewer_binary`), checked to be release `wanted` (`rerun --version`)."""
    binary = viewer_binary("serve Rerun's web viewer")
    try:
        said = subprocess.run([binary, "--version"], capture_output=True, text=True, timeout=60, env=_environment()).stdout
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise UserError(f"cannot run the rerun binary {binary}: {exc}") from None
    found = said.split()[1] if len(said.split()) > 1 else said.strip()
    if found != wanted:
        raise UserError(
            f"the rerun binary {binary} is release {found or 'unknown'}, not the installed rerun-sdk {wanted}; reinstall rerun-sdk"
        )
    return binary


def _environment() -> dict[str, str]:
    """`CI` keeps Rerun's usage analytics off (its native pipeline's own rule); `RERUN_APP_ONLY` its first-run prompt."""
    return {**os.environ, "CI": "1", "RERUN_APP_ONLY": "true", "RUST_LOG": "info"}


@contextlib.contextmanager
def serving_web_viewer(binary: str, folder: Path) -> Iterator[int]:
    """`rerun --serve-web` on 127.0.0.1 for the duration of the block; yields the web viewer's HTTP port."""
    log_path = folder / "rerun.log"
    args = ["--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", "0", "--port", "0"]
    with open(log_path, "wb") as log:
        process = start_viewer(binary, args, log, folder, _environment())
    try:
        yield _announced_port(process, log_path)
    finally:
        stop_session(process)


def _announced_port(process: subprocess.Popen[bytes], log_path: Path) -> int:
    """The port the binary says it hosts the web viewer on (its log line), once it says so."""
    deadline = time.monotonic() + STARTUP_SECONDS
    while True:
        text = log_path.read_text(encoding="utf-8", errors="replace")
        found = HOSTING.search(text)
        if found:
            return int(found.group(1))
        if process.poll() is not None or time.monotonic() > deadline:
            last = [line for line in text.splitlines() if line.strip()][-1:] or ["(no output)"]
            state = f"stopped (exit status {process.returncode})" if process.returncode is not None else "did not start"
            raise UserError(f"the rerun binary serving the web viewer {state} within {STARTUP_SECONDS:.0f} s: {last[0][:300]}")
        time.sleep(0.05)

"""The web viewer's files, taken from the installed rerun-sdk's own binary: the pinned release, checked, cached per
version (whole or not at all, one fetch for two processes), and the binary stopped afterwards."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import urllib.error
import urllib.request
from importlib.metadata import version
from pathlib import Path

import pytest

import urdf_pipeline.web.viewer_cache as cache_module
from urdf_pipeline.web import CACHE_VARIABLE, ViewerAssets, viewer_assets
from urdf_pipeline.web.viewer_cache import FILES, INDEX, cache_root, rerun_binary, serving_web_viewer

from ..conftest import REPO


def test_the_cached_viewer_is_the_installed_release(viewer_cache: ViewerAssets) -> None:
    import rerun

    assert viewer_cache.rerun_version == rerun.__version__ == version("rerun-sdk")
    assert viewer_cache.folder.name == rerun.__version__
    assert viewer_cache.path("re_viewer_bg.wasm").read_bytes()[:4] == b"\0asm"
    assert viewer_cache.path("re_viewer_bg.wasm").stat().st_size > 10_000_000
    assert "WebHandle" in viewer_cache.path("re_viewer.js").read_text()
    index = json.loads(viewer_cache.path(INDEX).read_text())
    assert index["rerun"] == rerun.__version__ and set(index["files"]) == set(FILES)
    for name in (*FILES, INDEX):  # sites hard-link them: nobody edits them in place by accident
        assert not viewer_cache.path(name).stat().st_mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH)


def test_a_cached_viewer_does_not_start_the_binary(viewer_cache: ViewerAssets, monkeypatch: pytest.MonkeyPatch) -> None:
    def no_binary(wanted: str) -> str:
        raise AssertionError("the rerun binary was started although the viewer is in the cache")

    monkeypatch.setattr(cache_module, "rerun_binary", no_binary)
    assert viewer_assets() == viewer_cache


def test_a_damaged_copy_is_fetched_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(CACHE_VARIABLE, str(tmp_path))
    first = viewer_assets()
    wasm = first.path("re_viewer_bg.wasm")
    wasm.chmod(0o644)
    with open(wasm, "r+b") as damaged:  # a disk that filled, a file cut short
        damaged.truncate(1000)
    again = viewer_assets()
    assert again.folder == first.folder and again.path("re_viewer_bg.wasm").stat().st_size > 10_000_000
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == [first.rerun_version]


def test_two_processes_share_one_fetch(tmp_path: Path) -> None:
    """Both see the whole viewer (one fetches, the other waits for it); nothing partial is left in the cache."""
    code = "from urdf_pipeline.web import viewer_assets; a = viewer_assets(); print(a.folder, a.size)"
    environment = {**os.environ, CACHE_VARIABLE: str(tmp_path), "PYTHONPATH": str(REPO)}
    processes = [
        subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=environment)
        for _ in range(2)
    ]
    results = [process.communicate(timeout=300) for process in processes]
    assert [process.returncode for process in processes] == [0, 0], results
    assert results[0][0] == results[1][0]
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == [version("rerun-sdk")]


def test_the_cache_is_per_user_unless_pointed_elsewhere(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(CACHE_VARIABLE, str(tmp_path / "chosen"))
    assert cache_root() == tmp_path / "chosen"
    monkeypatch.delenv(CACHE_VARIABLE)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "urdf-pipeline" / "web-viewer"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_root() == Path.home() / ".cache" / "urdf-pipeline" / "web-viewer"


def test_the_binary_serves_on_this_machine_only_and_stops(tmp_path: Path) -> None:
    binary = rerun_binary(version("rerun-sdk"))
    with serving_web_viewer(binary, tmp_path) as port:
        opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
        with opener.open(f"http://127.0.0.1:{port}/favicon.ico", timeout=30) as answer:
            assert answer.status == 200
        log = (tmp_path / "rerun.log").read_text(errors="replace")
        assert "0.0.0.0" not in log and f"127.0.0.1:{port}" in log
    with pytest.raises(urllib.error.URLError):
        opener.open(f"http://127.0.0.1:{port}/favicon.ico", timeout=5)

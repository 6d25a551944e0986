"""Fixtures of the source tests: the download cache of a test's own (remote sources)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The folder of this test's download cache (URDF_PIPELINE_CACHE), for the remote sources' tests."""
    folder = tmp_path / "download-cache"
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(folder))
    return folder


def cached_files(cache: Path) -> list[Path]:
    """The data files in the download cache: not its own lock and ledger files, nor parquet footers (metadata kept per
    ETag, so a re-run reads none again)."""
    found = cache.rglob("*") if cache.exists() else []
    return sorted(p for p in found if p.is_file() and not p.name.startswith(".") and not p.name.endswith(".footer"))

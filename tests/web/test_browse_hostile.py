"""`browse` of a run whose manifest (or `--base` folder) a stranger wrote: every file it would publish passes the read
rule and is a recording the tool wrote, or `browse` refuses with one located line, exit 1, and no site (an older site
left as it was). Each hostile manifest is built here from a real run's."""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from urdf_pipeline.web import ViewerAssets

from ..conftest import S3, CliResult
from .test_browse_site import base_recording, run_variant, site_data

SECRET = "AKIA-not-for-the-site"


@pytest.fixture(scope="module")
def written(examples_dir: Path) -> Path:
    """One run of the split so101 dataset for the module's tests; each test edits its manifest and puts it back."""
    return run_variant(examples_dir, "so101_browse_hostile")


@pytest.fixture
def manifest(written: Path) -> Iterator[Path]:
    path = next((written.parent / "out" / "so101_browse_hostile").glob("*.manifest.json"))
    kept = path.read_bytes()
    yield path
    path.write_bytes(kept)


def edit(manifest: Path, change: Callable[[dict[str, Any]], None]) -> None:
    data = json.loads(manifest.read_text(encoding="utf-8"))
    change(data)
    manifest.write_text(json.dumps(data), encoding="utf-8")


def name_in_entry(manifest: Path, value: str) -> None:
    def change(data: dict[str, Any]) -> None:
        data["segments"][1]["path"] = value

    edit(manifest, change)


def assert_refused(result: CliResult, manifest: Path, site: Path, *words: str) -> None:
    """One `error:` line naming the manifest and the entry, exit 1, no traceback, no secret, no site."""
    lines = result.err.strip().splitlines()
    assert result.code == 1, result.err
    assert len(lines) == 1 and lines[0].startswith(f"error: {manifest}: segments[1].path: "), result.err
    assert all(word in lines[0] for word in words), lines[0]
    assert "Traceback" not in result.err and SECRET not in result.err + result.out
    assert not site.exists() and not [p for p in site.parent.iterdir() if p.name.startswith(f".{site.name}.")]


def hostile_files(tmp_path: Path, out: Path) -> dict[str, str]:
    """Entry paths a stranger's manifest may hold, relative to the manifest's folder where they must be."""
    home = tmp_path / "home" / ".aws"
    home.mkdir(parents=True)
    (home / "credentials").write_text(f"[default]\naws_secret_access_key = {SECRET}\n")
    for name, text in (("x.html", "<script>alert(1)</script>"), ("x.js", "alert(1)"), ("x.svg", "<svg onload=alert(1)/>")):
        (out / name).write_text(text)
    outside = tmp_path / "outside"
    outside.mkdir()
    ours = sorted(out.glob("episode_*.rrd"))[0]
    shutil.copy(ours, outside / "ours.rrd")  # a recording the tool wrote, but outside every read root
    (out / "out_link.rrd").symlink_to(outside / "ours.rrd")
    (out / "in_link.rrd").symlink_to(ours)  # inside the folder, but no run writes a symbolic link
    (out / "secret_link.rrd").symlink_to(home / "credentials")
    base_recording(out / "foreign.rrd", "episode_000001")  # a Rerun recording another tool wrote
    os.mkfifo(out / "fifo.rrd")
    return {
        "proc": "/proc/self/environ",
        "credentials": str(home / "credentials"),
        "home": "~/.aws/credentials",
        "dots": "../" * 12 + "etc/passwd",
        "out_link": "out_link.rrd",
        "in_link": "in_link.rrd",
        "secret_link": "secret_link.rrd",
        "html": "x.html",
        "js": "x.js",
        "svg": "x.svg",
        "data": "../../data/so101_lerobot/meta/info.json",  # inside the read roots, but no recording
        "manifest": next(out.glob("*.manifest.json")).name,
        "foreign": "foreign.rrd",
        "blueprint": "so101_browse_hostile.rbl",  # the run's, but a blueprint, not a recording
        "fifo": "fifo.rrd",
        "nul": "episode\u0000.rrd",
    }


WHY = {
    "proc": "is outside",
    "credentials": "is outside",
    "home": "is outside",
    "dots": "is outside",
    "out_link": "is outside",
    "secret_link": "is outside",
    "in_link": "symbolic link",
    "html": "not a Rerun recording",
    "js": "not a Rerun recording",
    "svg": "not a Rerun recording",
    "data": "not a Rerun recording",
    "manifest": "not a Rerun recording",
    "foreign": "urdf-pipeline did not write",
    "blueprint": "not a Rerun recording",
    "fifo": "FIFO",
    "nul": "NUL",
}


def test_every_hostile_entry_is_refused_and_no_site_is_left(
    written: Path, manifest: Path, tmp_path: Path, viewer_cache: ViewerAssets, run_cli
) -> None:
    entries = hostile_files(tmp_path, manifest.parent)
    assert set(entries) == set(WHY)
    kept = manifest.read_bytes()
    for label, value in entries.items():
        manifest.write_bytes(kept)
        name_in_entry(manifest, value)
        site = tmp_path / f"site_{label}"
        assert_refused(run_cli("browse", str(written), "-o", str(site)), manifest, site, WHY[label])


def test_an_older_site_is_left_as_it_was(written: Path, manifest: Path, tmp_path: Path, viewer_cache: ViewerAssets, run_cli) -> None:
    site = tmp_path / "site"
    assert run_cli("browse", str(written), "-o", str(site), "-q").code == 0
    before = {p: p.read_bytes() for p in site.rglob("*") if p.is_file() and "viewer" not in p.parts}
    name_in_entry(manifest, "/proc/self/environ")
    result = run_cli("browse", str(written), "-o", str(site))
    assert result.code == 1 and "segments[1].path" in result.err
    assert {p: p.read_bytes() for p in site.rglob("*") if p.is_file() and "viewer" not in p.parts} == before
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".site.")]


def test_a_model_or_blueprint_swapped_for_a_link_is_refused(
    written: Path, manifest: Path, tmp_path: Path, viewer_cache: ViewerAssets, run_cli
) -> None:
    """The split layout's model and the blueprint go into the site too: a link in their place to a page, to a
    recording of the wrong kind, or out of the folder is refused (the config's paths are resolved when it compiles)."""
    out = manifest.parent
    (out / "x.html").write_text("<script>alert(1)</script>")
    (tmp_path / "credentials").write_text(SECRET)
    cases = [
        ("model.rrd", out / "x.html", "not a Rerun recording"),
        ("so101_browse_hostile.rbl", next(out.glob("episode_*.rrd")), "symbolic link"),  # not resolved by compile: refused as a link
        ("model.rrd", tmp_path / "credentials", "is outside"),
    ]
    for name, target, why in cases:
        kept = out / f"{name}.kept"
        os.rename(out / name, kept)
        (out / name).symlink_to(target)
        try:
            site = tmp_path / "site"
            result = run_cli("browse", str(written), "-o", str(site))
            lines = result.err.strip().splitlines()
            assert result.code == 1 and len(lines) == 1, result.err
            assert lines[0].startswith(f"error: {written}:") and why in lines[0] and SECRET not in result.err
            assert not site.exists()
        finally:
            (out / name).unlink()
            os.rename(kept, out / name)


def test_recordings_go_in_under_the_sites_names(written: Path, manifest: Path, tmp_path: Path, viewer_cache: ViewerAssets, run_cli) -> None:
    """A recording of the run renamed `x.html` by its manifest is still a recording: it goes in as `NNNNNN.rrd`."""
    out = manifest.parent
    first = json.loads(manifest.read_text())["segments"][0]
    os.rename(out / first["path"], out / "x.html")
    try:
        edit(manifest, lambda data: data["segments"][0].update(path="x.html"))
        site = tmp_path / "site"
        assert run_cli("browse", str(written), "-o", str(site), "-q").code == 0
        files = {p.relative_to(site).as_posix() for p in site.rglob("*") if p.is_file()}
        assert not [f for f in files if f.startswith("recordings/") and not f.endswith((".rrd", ".rbl"))]
        assert "recordings/000000.rrd" in files and not [f for f in files if f.endswith("/x.html") or f == "x.html"]
        assert not re.search(r"[/=\"]x\.html", (site / "segments.json").read_text()) and site_data(site)["segments"][0]["href"]
    finally:
        os.rename(out / "x.html", out / first["path"])


def test_a_base_file_linked_out_of_its_folder_is_refused(written: Path, tmp_path: Path, viewer_cache: ViewerAssets, run_cli) -> None:
    base = tmp_path / "base"
    base_recording(base / "episode_000000.rrd", "episode_000000")
    (tmp_path / "credentials").write_text(SECRET)
    (base / "episode_000001.rrd").symlink_to(tmp_path / "credentials")
    for given in (str(base), str(base / "*.rrd")):
        site = tmp_path / "site"
        result = run_cli("browse", str(written), "-o", str(site), "--base", given)
        assert result.code == 1 and len(result.err.strip().splitlines()) == 1, result.err
        assert result.err.startswith("error: --base: base recording") and "outside" in result.err and "symbolic link" in result.err
        assert SECRET not in result.err and not site.exists()
    (base / "episode_000001.rrd").unlink()
    os.mkfifo(base / "episode_000001.rrd")
    result = run_cli("browse", str(written), "-o", str(tmp_path / "site"), "--base", str(base))
    assert result.code == 1 and "FIFO" in result.err and not (tmp_path / "site").exists()


def test_a_bucket_manifest_naming_other_objects_is_refused(
    remote_dataset: Path, s3: S3, tmp_path: Path, viewer_cache: ViewerAssets, run_cli
) -> None:
    """Outputs in S3: an entry's URL outside the run's prefix is refused before anything is fetched, and an object
    under it that is not a recording the tool wrote (a page uploaded beside the recordings) after its download."""
    assert run_cli("run", str(remote_dataset), "--jobs", "2", "-q").code == 0
    client = s3.client()
    key = "so101/so101_dataset.manifest.json"
    kept = client.get_object(Bucket=s3.bucket, Key=key)["Body"].read()
    page = client.put_object(Bucket=s3.bucket, Key="so101/x.html", Body=b"<script>alert(1)</script>", ContentType="text/html")
    page["ETag"] = page["ETag"].strip('"')  # as the listing gives it, and the run records it
    elsewhere = client.put_object(Bucket=s3.bucket, Key="secrets/env", Body=SECRET.encode())
    for url, etag, why in (
        (s3.url("secrets/env"), elsewhere["ETag"], "not under the run's outputs"),
        ("s3://another-bucket/so101/episode_000000.rrd", elsewhere["ETag"], "not under the run's outputs"),
        (s3.url("so101/x.html"), page["ETag"], "not a Rerun recording"),
    ):
        data = json.loads(kept)
        data["segments"][1].update(url=url, etag=etag)
        client.put_object(Bucket=s3.bucket, Key=key, Body=json.dumps(data).encode())
        shutil.rmtree(tmp_path / "staging", ignore_errors=True)
        site = tmp_path / "site"
        result = run_cli("browse", str(remote_dataset), "-o", str(site))
        lines = result.err.strip().splitlines()
        assert result.code == 1 and len(lines) == 1 and "segments[1]" in lines[0] and why in lines[0], (url, result.err)
        assert SECRET not in result.err and "Traceback" not in result.err and not site.exists()


@pytest.mark.parametrize(
    ("change", "words"),
    [
        (lambda data: data.update(pad="x" * (25 << 20)), ("is over 24 MiB",)),  # bytes, counted as read
        (lambda data: data.update(pad=[{}] * 800_000), ("1,500,000 JSON values",)),  # 5 MB that would parse to 60 MB
        (
            lambda data: data["segments"].extend({"segment": f"s{i:06d}", "path": f"{i}.rrd"} for i in range(20_001)),
            ("segments: lists 20,005 segments",),
        ),
        (
            lambda data: data["segments"][1].update(path=data["segments"][0]["path"]),
            ("segments[1].path", "names the file segments[0].path"),
        ),
    ],
)
def test_a_manifest_too_big_or_naming_one_file_twice_is_refused(
    written: Path, manifest: Path, tmp_path: Path, change: Callable[[dict[str, Any]], None], words: tuple[str, ...], run_cli
) -> None:
    """What a reader of a stranger's manifest takes is bounded before it parses it, and each file is one segment's."""
    edit(manifest, change)
    site = tmp_path / "site"
    result = run_cli("browse", str(written), "-o", str(site))
    lines = result.err.strip().splitlines()
    assert result.code == 1 and len(lines) == 1 and lines[0].startswith(f"error: {manifest}: "), result.err
    assert all(word in lines[0] for word in words), lines[0]
    assert not site.exists()

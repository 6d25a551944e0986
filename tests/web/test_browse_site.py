"""`urdf-pipeline browse CONFIG -o DIR`: the site it writes from a run's manifest (no browser here; see
test_browse_page.py): the split layout's links, segments that lack a file or a summary, hostile strings kept inert,
10,000 segments, a config never run, and `--base` (base recordings opened with their layer, a row note without)."""

from __future__ import annotations

import json
import re
import time
from pathlib import Path
from typing import Any

from urdf_pipeline import cli
from urdf_pipeline.execute import SegmentSummary
from urdf_pipeline.web import ViewerAssets
from urdf_pipeline.web.browse_site import BrowseSegment, Shared, build_browser

from ..conftest import CliResult


def so101_variant(examples_dir: Path, name: str, single: bool = False) -> Path:
    """configs/so101_dataset.yaml writing into out/NAME (a run of its own: tests may break its outputs); `single`:
    in the single layout (each recording holds the model)."""
    config = examples_dir / f"{name}.yaml"
    text = (examples_dir / "so101_dataset.yaml").read_text(encoding="utf-8").replace("out/so101_dataset", f"out/{name}")
    if single:
        text = re.sub(r"\n  model: [^\n]*", "", text.replace("layout: split", "layout: single"))
    config.write_text(text, encoding="utf-8")
    return config


def run_variant(examples_dir: Path, name: str, single: bool = False) -> Path:
    config = so101_variant(examples_dir, name, single)
    assert cli.main(["run", str(config), "--jobs", "1", "-q"]) == 0
    return config


def site_data(site: Path) -> dict[str, Any]:
    data = json.loads((site / "segments.json").read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def test_the_split_layout_opens_model_layer_and_blueprint(examples_dir: Path, viewer_cache: ViewerAssets, tmp_path: Path, run_cli) -> None:
    config = run_variant(examples_dir, "so101_browse_split")
    result: CliResult = run_cli("browse", str(config), "-o", str(tmp_path / "site"))
    assert result.code == 0, result.err
    site = tmp_path / "site"
    assert result.out.strip().splitlines()[-1] == str(site)  # after the run's own lines (capsys holds both)
    data = site_data(site)
    segments = data["segments"]
    assert [s["id"] for s in segments] == sorted(s["id"] for s in segments) and len(segments) >= 2
    first = segments[0]
    assert first["href"] == (  # the model is added to the layer's recording (boot.js), not opened as a recording of its own
        "viewer/index.html#url=../recordings/000000.rrd&url=../recordings/shared/blueprint.rbl"
        f"&asset=../recordings/shared/model.rrd&into={first['id']}"
    )
    for path in ("recordings/shared/model.rrd", "recordings/shared/blueprint.rbl", "recordings/000000.rrd", "browse.js"):
        assert (site / path).is_file(), path
    assert first["robots"] == ["so101"] and first["frames"] > 0 and first["time"].endswith(" s on time")  # LeRobot's timestamps
    spark = first["spark"]
    assert spark["b"] <= 16 and 1 <= len(spark["j"]) <= 6 and {data["names"][i] for i in spark["r"]} == {"so101"}
    index = (site / "index.html").read_text(encoding="utf-8")
    assert '<script src="browse.js" defer></script>' in index and "<script>" not in index
    assert 'data-src="segments.json"' in index and '<iframe id="viewer"' in index


def test_a_missing_file_and_an_old_entry_still_get_a_row(examples_dir: Path, viewer_cache: ViewerAssets, tmp_path: Path) -> None:
    config = run_variant(examples_dir, "so101_browse_missing")
    out = examples_dir / "out" / "so101_browse_missing"
    manifest_path = next(out.glob("*.manifest.json"))
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    old, gone = manifest["segments"][0], manifest["segments"][1]
    del old["summary"]  # as a run before summaries wrote it
    manifest_path.write_text(json.dumps(manifest), encoding="utf-8")
    (out / Path(gone["path"]).name).unlink()
    assert cli.main(["browse", str(config), "-o", str(tmp_path / "site"), "-q"]) == 0
    rows = {s["id"]: s for s in site_data(tmp_path / "site")["segments"]}
    assert "no summary" in rows[old["segment"]]["missing"] and rows[old["segment"]]["href"]
    assert "spark" not in rows[old["segment"]]
    assert "no written file" in rows[gone["segment"]]["missing"] and "href" not in rows[gone["segment"]]
    assert len(rows) == len(manifest["segments"])


def test_a_config_never_run_is_a_located_error_naming_the_fix(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = so101_variant(examples_dir, "so101_browse_never")
    result = run_cli("browse", str(config), "-o", str(tmp_path / "site"))
    assert result.code == 1
    assert re.search(r"error: .*so101_browse_never\.yaml:\d+:\d+: output: no manifest at .*run `urdf-pipeline run .*` first", result.err)
    assert not (tmp_path / "site").exists()


HOSTILE = '<script>alert("id")</script>\u202e"\'&\x1b[31m'


def summary(robot: str, joints: int, note: str) -> SegmentSummary:
    buckets = 32
    parsed = SegmentSummary.from_json(
        {
            "robots": [robot],
            "timelines": [
                {"timeline": "log_time", "kind": "timestamp", "first": 1_700_000_000_000_000_000, "last": 1_700_000_012_500_000_000}
            ],
            "notes": [note],
            "notes_left_out": 3,
            "preview": [
                {
                    "robot": robot,
                    "rows": 900,
                    "buckets": buckets,
                    "joints": [f"joint_{j}" for j in range(joints)],
                    "low": [-1.0] * joints,
                    "high": [1.0] * joints,
                    "limited": [True] * joints,
                    "codes": __import__("base64").b64encode(bytes(([10] * buckets + [200] * buckets) * joints)).decode(),
                }
            ],
        }
    )
    assert parsed is not None
    return parsed


def test_hostile_ids_notes_and_file_names_stay_inert(viewer_cache: ViewerAssets, tmp_path: Path) -> None:
    files = [tmp_path / ".hidden.rrd", tmp_path / "a" / "same.rrd", tmp_path / "b" / "same.rrd", tmp_path / 'x"<y>.rrd']
    for path in files:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"RRF2")
    rows = [
        (BrowseSegment(f"{HOSTILE}{i}", 10, summary(HOSTILE, 2, f"<img src=x onerror=alert(1)>{HOSTILE}")), p) for i, p in enumerate(files)
    ]
    site = tmp_path / "site"
    build_browser(site, HOSTILE, rows, Shared(None, None))
    index = (site / "index.html").read_text(encoding="utf-8")
    assert "<script>alert" not in index and "&lt;script&gt;alert" in index and "\x1b" not in index
    data = site_data(site)
    assert data["segments"][0]["id"].startswith('<script>alert("id")</script>')  # data, shown as text by browse.js
    assert "\x1b" not in json.dumps(data, ensure_ascii=False) and "\\x1b" in data["segments"][0]["id"]
    assert data["segments"][0]["notes"][0].startswith("<img src=x")
    names = sorted(p.name for p in (site / "recordings").iterdir())
    assert names == ["000000.rrd", "000001.rrd", "000002.rrd", "000003.rrd"]  # the site's names, never the files'
    assert [s["href"].count("url=") for s in data["segments"]] == [1, 1, 1, 1]
    assert not [s for s in data["segments"] if "same" in s["href"] or "hidden" in s["href"] or "%253Cy" in s["href"]]
    script = (Path(__file__).parents[2] / "urdf_pipeline" / "web" / "static" / "browse.js").read_text(encoding="utf-8")
    assert "innerHTML" not in script and "insertAdjacentHTML" not in script and "document.write" not in script


def test_ten_thousand_segments(viewer_cache: ViewerAssets, tmp_path: Path) -> None:
    """The site of 10,000 segments, each with a summary of 2 robots x 8 joints: segments.json stays a few MB."""
    recording = tmp_path / "in" / "x.rrd"
    recording.parent.mkdir()
    recording.write_bytes(b"RRF2" * 64)
    both = summary("left_arm", 8, "values of joint_3 clamped to its limits in 12 rows")
    left, right = both.previews[0], summary("right_arm", 8, "").previews[0]
    shared_summary = SegmentSummary(("left_arm", "right_arm"), both.timelines, both.notes, 0, (left, right))
    rows = [(BrowseSegment(f"episode_{i:06d}", 900, shared_summary), recording) for i in range(10_000)]
    started = time.perf_counter()
    result = build_browser(tmp_path / "site", "big", rows, Shared(recording, None))
    seconds = time.perf_counter() - started
    data_bytes = (tmp_path / "site" / "segments.json").stat().st_size
    print(f"10,000 segments: site built in {seconds:.2f} s, segments.json {data_bytes / 1e6:.2f} MB")
    assert result.segments == 10_000 and result.missing == 0
    assert data_bytes < 8_000_000
    data = site_data(tmp_path / "site")
    assert len(data["segments"]) == 10_000 and len(data["names"]) == 2 + 3  # robots and joints interned once (6 joints: 3 per robot)
    assert len(list((tmp_path / "site" / "recordings").iterdir())) == 10_001  # one made name each, and shared/


def base_recording(path: Path, recording_id: str, application_id: str = "so101_dataset", timeline: str = "tick") -> None:
    """A base recording as an importer would write it: a few scalars under the segment's id, on `timeline`."""
    import rerun as rr

    stream = rr.RecordingStream(application_id=application_id, recording_id=recording_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    stream.save(str(path))
    for tick in range(3):
        stream.set_time(timeline, sequence=tick)
        stream.log("base/gripper_force", rr.Scalars(float(tick)))
    stream.disconnect()


def test_base_recordings_open_with_their_layer(examples_dir: Path, viewer_cache: ViewerAssets, tmp_path: Path, run_cli) -> None:
    config = run_variant(examples_dir, "so101_browse_base")
    ids = [
        s["segment"] for s in json.loads(next((examples_dir / "out" / "so101_browse_base").glob("*.manifest.json")).read_text())["segments"]
    ]
    base = tmp_path / "base"  # outside the config's folder: a command-line argument, read as `run --base` reads it
    base_recording(base / f"{ids[0]}.rrd", ids[0])
    base_recording(base / "nested" / '"><img src=x onerror=alert(1)>.rrd', ids[1], application_id=HOSTILE)
    result = run_cli("browse", str(config), "-o", str(tmp_path / "site"), "--base", str(base))
    assert result.code == 0, result.err
    rows = {s["id"]: s for s in site_data(tmp_path / "site")["segments"]}
    first, second, last = rows[ids[0]], rows[ids[1]], rows[ids[-1]]
    assert first["base"] == ["recordings/shared/base_000000.rrd"] and "missing" not in first
    assert first["href"] == (
        "viewer/index.html#url=../recordings/shared/base_000000.rrd&url=../recordings/000000.rrd"
        f"&url=../recordings/shared/blueprint.rbl&asset=../recordings/shared/model.rrd&into={ids[0]}"
    )
    assert (tmp_path / "site" / "recordings" / "shared" / "base_000000.rrd").samefile(base / f"{ids[0]}.rrd")
    assert second["base"] == ["recordings/shared/base_000001.rrd"] and "img" not in second["href"]  # the file's name never shows
    assert "application_id" in second["missing"] and "shows them apart" in second["missing"]
    assert "no base recording" in last["missing"] and "base" not in last and last["href"]
    shared = sorted(p.name for p in (tmp_path / "site" / "recordings" / "shared").iterdir())
    assert shared == ["base_000000.rrd", "base_000001.rrd", "blueprint.rbl", "model.rrd"]  # each base file once

    glob = run_cli("browse", str(config), "-o", str(tmp_path / "site"), "--base", str(base / "*.rrd"), "-q")
    assert glob.code == 0 and "base" in site_data(tmp_path / "site")["segments"][0]
    empty = tmp_path / "empty"
    empty.mkdir()
    refused = run_cli("browse", str(config), "-o", str(tmp_path / "other"), "--base", str(empty))
    assert refused.code == 1 and "--base" in refused.err and "no .rrd file in" in refused.err
    assert not (tmp_path / "other").exists()

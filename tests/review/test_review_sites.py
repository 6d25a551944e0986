"""`plan --html DIR` and `diff --html DIR` (also `diff --git REV --html DIR`), without a browser: the site's page
holds the report with every name from a stranger's config, URDF or file name inert (no tag, attribute, comment or
script of theirs), links only inside the site, one viewer copy, the rest pose (diff: old and new) as recordings the
page opens, the pictures of `--render` inline; stdout keeps the `--format` report; a folder that is not a site is
refused before any work. The browser tests of these sites are in tests/web/test_plan_diff_sites.py."""

from __future__ import annotations

import html
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from rerun.chunk import RrdReader

from urdf_pipeline.review.plan_report.report_html import pictures_html
from urdf_pipeline.review.plan_report.report_model import PictureEntry
from urdf_pipeline.web import MARKER, ViewerAssets

from ..render.conftest import renderer  # noqa: F401 (skips, saying why, without a Vulkan driver)
from ..web.conftest import viewer_cache  # noqa: F401 (the session's viewer cache: no test writes the user's)
from .site_checks import assert_inert_page, links
from .test_hostile_text import _workspace

CONFIGS = ["demo", "bimanual_pandas", "aloha_bimanual", "g1_held_joints", "so101_dataset", "so101_lerobot", "ur5_ros2_bag"]
# Names that would be markup, an attribute break, a script or a script URL if a page held them raw.
SCRIPT = '<script>alert("x")</script>'
ATTRIBUTE = '"><img src=x onerror=alert(1)>'
QUOTE = "' onmouseover='alert(1)"
URL = "javascript:alert(1)"
COMMENT = "</pre></code><!--"
LINKS = [SCRIPT, ATTRIBUTE, QUOTE, URL, COMMENT, "a&amp;b"]
JOINT = '"><svg onload=alert(1)>'
VALUE = "javascript:alert('q')"
STEMS = ["<script>ep", 'javascript:ep"x']  # fmt: skip (a file name holds no slash)
ROOT = "<script>world</script>"


@pytest.fixture(autouse=True)
def _cached_viewer(viewer_cache: ViewerAssets) -> None:  # noqa: F811
    """Every site here takes the viewer from the session's cache."""


def _hostile(folder: Path, links: list[str] = LINKS, joint: str = JOINT, translation: float = 0.0) -> Path:
    """A config whose link, joint, source value, file names (segment ids), root frame and edge carry hostile names."""
    config = _workspace(folder, links, joint, VALUE, STEMS)
    data = yaml.safe_load(config.read_text())
    data["frames"] = {"root": ROOT}
    data["edges"] = [{"parent": ROOT, "child": "base", "translation": [0.0, 0.0, translation], "quaternion_xyzw": [0, 0, 0, 1]}]
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    return config


def _recording(site: Path, name: str) -> tuple[str, str, str]:
    """A site recording's application id, recording id and the name the viewer's recording list shows."""
    reader = RrdReader(site / "recordings" / name)
    (entry,) = reader.recordings()
    properties = [c for c in reader.store().stream().to_chunks() if c.entity_path == "/__properties"]
    names = [row for chunk in properties for row in chunk.to_record_batch().column("RecordingInfo:name").to_pylist()]
    return entry.application_id, entry.recording_id, names[0][0]


def _assert_one_viewer(site: Path) -> None:
    assert (site / MARKER).is_file()
    assert len(list(site.rglob("*.wasm"))) == 1
    assert sorted(p.name for p in (site / "viewer").iterdir()) == [
        "boot.js",
        "favicon.ico",
        "index.html",
        "re_viewer.js",
        "re_viewer_bg.wasm",
    ]


# ------------------------------------------------------------------------------------------------ hostile names


def test_the_plan_page_shows_hostile_names_as_text(run_cli, tmp_path: Path) -> None:
    config = _hostile(tmp_path / "h")
    site = tmp_path / "site"
    result = run_cli("plan", str(config), "--html", str(site))
    assert result.code == 0, result.err
    page = assert_inert_page(site)
    text = (site / "index.html").read_text()
    for name in [*LINKS, JOINT, VALUE, *STEMS, ROOT]:
        assert html.escape(name) in text, name  # shown, escaped (quotes too)
    assert "<script" not in text and "<img" not in text and "<svg" not in text and "<!--" not in text
    assert [tag for tag, _ in page.tags].count("iframe") == 1
    shown = "".join(page.text)
    assert SCRIPT in shown and ATTRIBUTE in shown and URL in shown  # what a reader sees: the names as written
    _assert_one_viewer(site)


def test_the_diff_page_shows_hostile_names_as_text(run_cli, tmp_path: Path) -> None:
    old = _hostile(tmp_path / "old")
    new = _hostile(tmp_path / "new", links=LINKS[::-1][1:], joint=JOINT + "2", translation=0.005)
    site = tmp_path / "site"
    result = run_cli("diff", str(old), str(new), "--html", str(site))
    assert result.code == 0, result.err
    assert_inert_page(site)
    text = (site / "index.html").read_text()
    assert html.escape(ROOT) in text and html.escape(JOINT + "2") in text and html.escape(COMMENT) in text
    assert "<script" not in text and "<img" not in text and "<svg" not in text and "<!--" not in text
    assert "moved 5.0 mm" in text


def test_pictures_show_any_label_and_link_any_path_inside_the_site() -> None:
    pictures = [PictureEntry(SCRIPT, "pictures/plan-1.png"), PictureEntry(QUOTE, 'pictures/a "b"#c d.png')]
    shown = pictures_html(pictures, "index.html", "note")
    assert html.escape(SCRIPT) in shown and html.escape(QUOTE) in shown and "<script" not in shown
    assert 'src="pictures/a%20%22b%22%23c%20d.png"' in shown  # percent-encoded: no quote ends the attribute
    assert "--render DIR" in pictures_html([], "index.html", "note")  # without pictures: how to get them


# ------------------------------------------------------------------------------------------------ the sites


@pytest.mark.parametrize("name", CONFIGS)
def test_plan_html_of_every_example(run_cli, examples_dir: Path, tmp_path: Path, name: str) -> None:
    site = tmp_path / "site"
    result = run_cli("plan", str(examples_dir / f"{name}.yaml"), "--html", str(site))
    assert result.code == 0, result.err
    page = assert_inert_page(site)
    _assert_one_viewer(site)
    application, recording, shown = _recording(site, "rest_pose.rrd")
    assert (recording, shown) == ("rest_pose", f"rest pose: {name}.yaml")
    assert application == yaml.safe_load((examples_dir / f"{name}.yaml").read_text())["output"]["application_id"]
    assert [entry.application_id for entry in RrdReader(site / "recordings" / "rest_pose.rbl").blueprints()] == [application]
    opened = "viewer/index.html#url=../recordings/rest_pose.rrd&url=../recordings/rest_pose.rbl"
    assert links(page, "iframe", "src") == [opened] and opened in links(page)
    assert "--render DIR" in (site / "index.html").read_text()  # no pictures: the page says how to get them
    assert f"site written to {site}" in result.err and "urdf-pipeline serve" in result.err


@pytest.fixture
def workspace(examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder of its own (in no git repository) with the demo config; robots/ and data/ are the session's examples."""
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    work = tmp_path / "work"
    work.mkdir()
    for name in ("robots", "data"):
        (work / name).symlink_to(examples_dir / name, target_is_directory=True)
    shutil.copy(examples_dir / "demo.yaml", work / "demo.yaml")
    return work


def test_diff_html_opens_old_and_new_apart(run_cli, workspace: Path, tmp_path: Path) -> None:
    old = workspace / "demo.yaml"
    new = workspace / "moved.yaml"
    new.write_text(old.read_text().replace("translation: [0.0, 0.0, 0.5]", "translation: [0.0, 0.0, 0.505]"))
    site = tmp_path / "site"
    result = run_cli("diff", str(old), str(new), "--html", str(site), "--exit-code")
    assert result.code == 1, result.err  # --exit-code still says they differ; the site is written all the same
    page = assert_inert_page(site)
    _assert_one_viewer(site)
    assert _recording(site, "old.rrd") == ("panda_demo", "old", f"old: {old}")
    assert _recording(site, "new.rrd") == ("panda_demo", "new", f"new: {new}")
    both = "viewer/index.html#url=../recordings/old.rrd&url=../recordings/old.rbl&url=../recordings/new.rrd&url=../recordings/new.rbl"
    assert links(page, "iframe", "src") == [both]
    assert [link for link in links(page) if link.startswith("viewer/")] == [
        both,
        "viewer/index.html#url=../recordings/old.rrd&url=../recordings/old.rbl",
        "viewer/index.html#url=../recordings/new.rrd&url=../recordings/new.rbl",
    ]
    assert "edge world -&gt; panda_link0" in (site / "index.html").read_text() and "moved 5.0 mm" in "".join(page.text)


def test_diff_git_html(run_cli, workspace: Path, tmp_path: Path) -> None:
    work, config = workspace, workspace / "demo.yaml"
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@example.com", "-c", "commit.gpgsign=false"]
    for command in (["init", "-q"], ["add", "demo.yaml"], ["commit", "-qm", "demo"]):
        subprocess.run([*git, *command], cwd=work, check=True, capture_output=True)
    config.write_text(config.read_text().replace("j3: {joint: panda_joint3, offset: 0.1}", "j3: {joint: panda_joint3, offset: 0.2}"))
    site = tmp_path / "site"
    result = run_cli("diff", str(config), "--git", "HEAD", "--html", str(site))
    assert result.code == 0, result.err
    assert "offset 0.1 -&gt; 0.2" in (site / "index.html").read_text()
    assert _recording(site, "old.rrd")[1:] == ("old", f"old: {config}@HEAD") and _recording(site, "new.rrd")[1:] == (
        "new",
        f"new: {config}",
    )
    assert_inert_page(site)


def test_stdout_keeps_the_format_and_a_site_replaces_only_a_site(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    config = str(examples_dir / "demo.yaml")
    site = tmp_path / "site"
    for format in ("markdown", "json", "text"):
        assert run_cli("plan", config, "--format", format, "--html", str(site)).out == run_cli("plan", config, "--format", format).out
    assert (site / "index.html").is_file()  # the last one replaced the earlier sites
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]  # nothing left beside it
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    for command in (["plan", config], ["diff", config, config]):
        result = run_cli(*command, "--html", str(mine))
        assert result.code == 1 and result.err.startswith(f"error: {mine}: is a folder that is not a site urdf-pipeline wrote")
        assert "site written" not in result.err and result.out == ""
    assert [p.name for p in mine.iterdir()] == ["thesis.tex"]


def test_a_config_error_writes_no_site(run_cli, tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("version: 1\nrobots: {}\n")
    result = run_cli("plan", str(broken), "--html", str(tmp_path / "site"))
    assert result.code == 1 and result.err.startswith("error: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.yaml"]  # no site, no partial folder


def test_render_puts_the_pictures_into_the_site(run_cli, examples_dir: Path, tmp_path: Path, renderer: None) -> None:  # noqa: F811
    site = tmp_path / "site"
    result = run_cli("plan", str(examples_dir / "bimanual_pandas.yaml"), "--render", str(tmp_path / "pictures"), "--html", str(site))
    assert result.code == 0, result.err
    page = assert_inert_page(site)
    assert sorted(p.name for p in (site / "pictures").iterdir()) == ["plan-1.png", "plan-2.png", "plan-3.png"]
    assert links(page, "img", "src") == ["pictures/plan-1.png", "pictures/plan-2.png", "pictures/plan-3.png"]
    assert "--render DIR" not in (site / "index.html").read_text()
    for number, label in enumerate(("scene", "left", "right"), start=1):
        drawn = tmp_path / "pictures" / f"bimanual_pandas.plan.{label}.png"
        assert (site / "pictures" / f"plan-{number}.png").read_bytes() == drawn.read_bytes()
        assert f"picture {label}: {drawn}" in result.out  # the text report names the files of --render's folder
        assert f"<figcaption>{label}</figcaption>" in (site / "index.html").read_text()


def test_the_sample_shows_in_the_page(run_cli, examples_dir: Path, tmp_path: Path) -> None:
    site = tmp_path / "site"
    result = run_cli("plan", str(examples_dir / "demo.yaml"), "--sample", "--rows", "50", "--html", str(site))
    assert result.code == 0, result.err
    assert_inert_page(site)
    text = (site / "index.html").read_text()
    assert "<th>observed (source units)</th>" in text and "sampled: the first 50 rows of source <code>arm_state</code>" in text

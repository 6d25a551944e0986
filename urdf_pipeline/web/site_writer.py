"""A static site written whole or not at all: built in a temporary folder beside its target, then put in its place.

A site is a folder holding `index.html` (the caller's), `style.css` (the shared stylesheet), `viewer/` (Rerun's web
viewer of the pinned release and our page that starts it: one copy per site), `recordings/` (the recordings its pages
open) and the marker file `.urdf-pipeline-site`, by which a later build knows the folder is one it may replace. Any
other existing folder (not empty, without the marker) is refused: it is not ours to delete.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from importlib.resources import files
from pathlib import Path

from ..confine import os_cause
from ..errors import UserError, Where
from ..package import __version__
from .page_html import STYLESHEET, VIEWER_POLICY, page
from .viewer_cache import FILES, ViewerAssets, viewer_assets

MARKER = ".urdf-pipeline-site"
RECORDINGS = "recordings"
VIEWER = "viewer"


class SiteWriter:
    """The site being built (in a temporary folder): pages, files and recordings go in by their site path."""

    def __init__(self, root: Path, viewer: ViewerAssets | None) -> None:
        self.root = root
        self.viewer = viewer

    @property
    def rerun_version(self) -> str:
        return self.viewer.rerun_version if self.viewer is not None else ""

    def _place(self, site_path: str) -> Path:
        """The file for a site path (`a/b.html`), its folder created; a path leaving the site is a bug of the caller."""
        parts = site_path.split("/")
        if not site_path or site_path.startswith("/") or any(part in ("", ".", "..") for part in parts):
            raise ValueError(f"{site_path!r} is not a file path inside the site")
        target = self.root.joinpath(*parts)
        target.parent.mkdir(parents=True, exist_ok=True)
        return target

    def write_text(self, site_path: str, text: str) -> str:
        """Write a text file (UTF-8) at `site_path`; returns the site path."""
        self._place(site_path).write_text(text, encoding="utf-8")
        return site_path

    def write_page(self, site_path: str, title: str, body_html: str, scripts: Sequence[str] = ()) -> str:
        """`page(title, body_html, ...)` written at `site_path`; returns the site path."""
        return self.write_text(site_path, page(title, body_html, at=site_path, scripts=scripts, rerun=self.rerun_version))

    def add_file(self, source: Path, site_path: str) -> str:
        """A file put into the site at `site_path`, hard-linked when it can be (same file system), else copied; a
        source that cannot be read (missing, a folder, no permission) is a user error naming it."""
        try:
            link_or_copy(source, self._place(site_path))
        except OSError as exc:
            raise UserError(f"cannot put it into the site: {os_cause(exc, source)}", Where(source, 0)) from None
        return site_path

    def add_recording(self, source: Path, name: str | None = None) -> str:
        """A recording (`.rrd`, `.rbl`) put under `recordings/` as `name` (default: its file name), hard-linked or
        copied; returns its site path, for `viewer_href`. `name` is one file name (segment ids are)."""
        chosen = name if name is not None else source.name
        if not chosen or "/" in chosen or "\\" in chosen or "\0" in chosen or chosen.startswith("."):
            raise ValueError(f"{chosen!r} is not a plain file name for a recording")
        return self.add_file(source, f"{RECORDINGS}/{chosen}")


def link_or_copy(source: Path, target: Path) -> None:
    """A hard link when the file system allows it (no second copy of a 43 MB wasm), else a copy."""
    try:
        os.link(source, target)
    except OSError:
        shutil.copyfile(source, target)


@contextlib.contextmanager
def write_site(target: Path, viewer: bool = True) -> Iterator[SiteWriter]:
    """`with write_site(DIR) as site: site.write_page("index.html", ...)`: the site is built in a temporary folder
    beside DIR and replaces DIR when the block ends without an exception (otherwise DIR is left as it was). DIR must be
    absent, empty, or a site written before. With `viewer`, the site holds Rerun's web viewer under `viewer/`."""
    target = Path(target)
    _require_replaceable(target)
    assets = viewer_assets() if viewer else None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        building = Path(tempfile.mkdtemp(prefix=f".{target.name}.partial-", dir=target.parent))
    except OSError as exc:
        raise UserError(f"cannot write the site here: {exc.strerror or exc}", Where(target, 0)) from None
    try:
        site = SiteWriter(building, assets)
        _write_base(site)
        yield site
        if not (building / "index.html").is_file():
            raise ValueError("a site needs an index.html page")
        building.chmod(0o755)  # mkdtemp's 0o700 would hide the site from a web server running as another user
        _put_in_place(building, target)
    finally:
        if building.exists():
            shutil.rmtree(building, ignore_errors=True)


def _require_replaceable(target: Path) -> None:
    """DIR may be replaced when it does not exist, is an empty folder, or holds our marker (a site we wrote)."""
    if target.is_symlink() or (target.exists() and not target.is_dir()):
        raise UserError("is not a folder; the site is written as a new folder: choose another path", Where(target, 0))
    if target.is_dir() and not (target / MARKER).is_file() and any(target.iterdir()):
        raise UserError(
            f"is a folder that is not a site urdf-pipeline wrote (no {MARKER} in it), and writing the site would replace it; "
            "choose a new or empty folder",
            Where(target, 0),
        )


def _write_base(site: SiteWriter) -> None:
    """The marker, the stylesheet, `.nojekyll` (GitHub Pages serves the files as they are) and the viewer."""
    static = files(__package__) / "static"
    site.write_text(MARKER, json.dumps({"generator": "urdf-pipeline", "version": __version__, "rerun": site.rerun_version}) + "\n")
    site.write_text(".nojekyll", "")
    site.write_text(STYLESHEET, (static / "style.css").read_text(encoding="utf-8"))
    if site.viewer is None:
        return
    for name in FILES:
        site.add_file(site.viewer.path(name), f"{VIEWER}/{name}")
    site.write_text(f"{VIEWER}/boot.js", (static / "boot.js").read_text(encoding="utf-8"))
    template = (static / "viewer.html").read_text(encoding="utf-8")
    site.write_text(
        f"{VIEWER}/index.html",
        template.replace("{csp}", VIEWER_POLICY).replace("{version}", __version__).replace("{rerun}", site.rerun_version),
    )


def _put_in_place(building: Path, target: Path) -> None:
    """The finished site renamed to `target`; an older site there is renamed aside first, then removed."""
    aside = None
    if target.exists():
        aside = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
        os.rename(target, aside)  # onto the empty folder just made: a name no other build holds
    try:
        os.rename(building, target)
    except OSError:
        if aside is not None:
            os.rename(aside, target)  # the old site back, as it was
        raise
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)

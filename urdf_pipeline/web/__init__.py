"""Static sites on Rerun's own web viewer of the pinned release, and `serve` to look at them on this machine.

A site works offline and on any static host under any path prefix: every link is relative, every page carries a
Content-Security-Policy that runs the site's own scripts only, and nothing is requested from another host at view
time (no fonts, analytics or version check: the viewer page is ours, `viewer/index.html` + `viewer/boot.js`, not the
stock one). The 43 MB viewer is in a site once, under `viewer/`; pages open recordings in it by link.

The API, for the commands that write sites (`plan --html`, `diff --html`, `browse`):

    with write_site(Path(DIR)) as site:                      # built beside DIR, then put in its place
        rrd = site.add_recording(Path("out/episode_000.rrd"))  # -> "recordings/episode_000.rrd" (hard link or copy)
        href = viewer_href("index.html", [rrd])                # -> "viewer/index.html#url=../recordings/episode_000.rrd"
        body = f'<h1>{html_text(name)}</h1><a href="{href}">open in the viewer</a>'
        site.write_page("index.html", f"plan of {name}", body)  # every site needs an index.html

- `write_site(target, viewer=True) -> ContextManager[SiteWriter]`: DIR must be absent, empty or a site written before
  (its marker file `.urdf-pipeline-site`); anything else is a `UserError`. On an exception DIR stays as it was.
- `SiteWriter.write_page(site_path, title, body_html, scripts=()) -> str`, `.write_text(site_path, text) -> str`,
  `.add_file(source, site_path) -> str`, `.add_recording(source, name=None) -> str`: each returns the site path
  (POSIX, relative to the site's root) it wrote; `.root` is the folder being built, `.rerun_version` the viewer's.
- `page(title, body_html, at="index.html", scripts=(), rerun="") -> str`: the one HTML template (policy, the shared
  `style.css`, header and footer); `title` is escaped, `body_html` is the caller's HTML.
- `html_text(value, limit=200) -> str`: every string from input (config, URDF, data, file names) before it goes into
  HTML text or a quoted attribute: `html.escape(errors.shown(value))`, one line, shortened.
- `viewer_href(from_page, recordings) -> str` and `relative_href(from_page, target) -> str`: relative,
  percent-encoded links (safe in a quoted attribute as they are) from the page at site path `from_page`.
- `viewer_assets() -> ViewerAssets`: the pinned release's viewer files in the per-user cache (fetched from the
  rerun binary the first time; `URDF_PIPELINE_WEB_CACHE` points the cache elsewhere).
- `browse_config(plan, DIR, config_text) -> BrowseResult`: the `browse` command's dataset browser, from the run's
  manifest and its summaries only (`dataset.segment_summaries`).
- `serve_site(folder, port=0, ready=None)`, `SiteServer`, `site_folder(folder)`: the `serve` command's server.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .browse_site import BrowseResult, browse_config
    from .page_html import PAGE_POLICY, VIEWER_POLICY, html_text, page, relative_href, viewer_href
    from .site_writer import MARKER, SiteWriter, write_site
    from .static_server import SiteServer, serve_site, site_folder
    from .viewer_cache import CACHE_VARIABLE, ViewerAssets, viewer_assets

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

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

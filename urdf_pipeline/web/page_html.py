"""The site's HTML: one page template (its Content-Security-Policy, the shared stylesheet, relative links only), the
escape for text from input, and the relative link that opens recordings in the site's viewer.

Every link is relative to its page, so a site works under any path prefix; pages are named by their site-relative POSIX
path (`index.html`, `segments/episode_000.html`): that is what `at` and `from_page` mean below.
"""

from __future__ import annotations

import html
import posixpath
from collections.abc import Sequence
from urllib.parse import quote

from ..errors import NAME_LIMIT, shown
from ..package import __version__

STYLESHEET = "style.css"
VIEWER_PAGE = "viewer/index.html"
# A page runs only the site's own scripts (no inline script, no other origin), loads only the site's own styles,
# pictures and data, and may frame the site's viewer; nothing it holds can send a form or move its base URL.
PAGE_POLICY = (
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; "
    "frame-src 'self'; base-uri 'none'; form-action 'none'"
)
# The viewer page, as little as Rerun 0.41's viewer needs in chromium: compiling the wasm ('wasm-unsafe-eval'), fetching
# the recordings from the site (no inline style, worker, blob or data URL). Other origins' fetches never reach it: boot.js.
VIEWER_POLICY = (
    "default-src 'none'; script-src 'self' 'wasm-unsafe-eval'; style-src 'self'; img-src 'self'; connect-src 'self'; "
    "base-uri 'none'; form-action 'none'"
)


def html_text(value: object, limit: int = NAME_LIMIT) -> str:
    """Text from input (a config's names, a URDF's, a file name, a segment id) as HTML text or a quoted attribute's
    value: one line with control characters made visible and shortened past `limit` characters (`errors.shown`),
    then `<`, `>`, `&` and both quotes escaped. Never for a URL: shortening would break it (see `viewer_href`)."""
    return html.escape(shown(value, limit), quote=True)


def relative_href(from_page: str, target: str) -> str:
    """The link from the page at site path `from_page` to the site path `target`, percent-encoded (a `%`, `#`, `?`,
    space or quote in a file name stays part of the path): safe in a quoted attribute as it is."""
    for path in (from_page, target):
        if path.startswith("/") or ".." in path.split("/"):
            raise ValueError(f"{path!r} is not a path inside the site")
    relative = posixpath.relpath(target, posixpath.dirname(from_page) or ".")
    return quote(relative, safe="/")


def viewer_href(from_page: str, recordings: Sequence[str], asset: str | None = None, into: str | None = None) -> str:
    """The relative link, from the page at `from_page`, that opens the site's `recordings` (site paths of `.rrd` and
    `.rbl` files) together in the site's viewer: `viewer/index.html#url=../recordings/a.rrd&url=...`, each relative to
    the viewer page (boot.js resolves it). `asset` and `into`: a split layout's model (site path), added by boot.js to
    the recording whose recording id is `into`. Percent-encoded: safe in a quoted attribute as it is."""
    parts = [("url", relative_href(VIEWER_PAGE, recording)) for recording in recordings]
    if asset is not None and into is not None:
        parts += [("asset", relative_href(VIEWER_PAGE, asset)), ("into", into)]
    fragment = "&".join(f"{name}={quote(value, safe='/' if name != 'into' else '')}" for name, value in parts)
    return relative_href(from_page, VIEWER_PAGE) + (f"#{fragment}" if fragment else "")


def page(title: str, body_html: str, at: str = "index.html", scripts: Sequence[str] = (), rerun: str = "") -> str:
    """A whole page of the site at `at`: the policy, the shared stylesheet, a header linking the site's index, the
    body, a footer naming what made it. `title` is text from anywhere (escaped here); `body_html` is HTML the caller
    built with `html_text` for every string from input. `scripts`: site paths of the site's own scripts, deferred."""
    head = [
        "<!doctype html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{PAGE_POLICY}">',
        '<meta name="referrer" content="no-referrer">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{html_text(title)}</title>",
        '<link rel="icon" href="data:,">',  # no icon: else the browser asks the host's root for /favicon.ico
        f'<link rel="stylesheet" href="{relative_href(at, STYLESHEET)}">',
        *(f'<script src="{relative_href(at, script)}" defer></script>' for script in scripts),
        "</head>",
        "<body>",
        f'<header class="site"><nav><a class="brand" href="{relative_href(at, "index.html")}">urdf-pipeline</a></nav></header>',
        "<main>",
    ]
    made_by = f"urdf-pipeline {__version__}" + (f", Rerun {html_text(rerun)}" if rerun else "")
    tail = ["</main>", f'<footer class="site">Made by {made_by}.</footer>', "</body>", "</html>", ""]
    return "\n".join([*head, body_html, *tail])

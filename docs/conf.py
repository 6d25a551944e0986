"""Sphinx configuration of the documentation site (`make docs`): Markdown pages read by MyST, the furo theme.

The pages are also read on GitHub, so they link with plain relative paths: to each other (`commands.md#run`), and
to files of the repository outside `docs/` (`../ARCHITECTURE.md`). The site turns the latter into links to the file
on GitHub; a link to a file that does not exist stays an error of the strict build.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from docutils import nodes
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.transforms.post_transforms import SphinxPostTransform

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
_PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
SOURCE_URL = _PROJECT["urls"]["Source"]

project = "urdf-pipeline"
author = "urdf-pipeline contributors"
copyright = "urdf-pipeline contributors, Apache-2.0"
release = next(
    line.split("=", 1)[1].strip().strip("\"'")
    for line in (REPO / "urdf_pipeline" / "package.py").read_text(encoding="utf-8").splitlines()
    if line.startswith("__version__")
)

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "workflows"]
myst_heading_anchors = 3  # `page.md#a-heading` links, with GitHub's slugs
smartquotes = False  # `--force`, `...` and quotes in plain text stay as typed (options, YAML paths)
html_theme = "furo"
html_title = f"urdf-pipeline {release}"
html_show_sourcelink = False


class RepositoryLinks(SphinxPostTransform):
    """A link from a page to a file of the repository outside `docs/` becomes a link to that file on GitHub.

    MyST makes such a link a pending reference to a document it does not have (a Markdown file) or a download (any
    other file); both would be wrong on the site. Runs before MyST resolves references (priority 9)."""

    default_priority = 8

    def run(self, **kwargs: Any) -> None:
        for node in list(self.document.findall(addnodes.pending_xref)) + list(self.document.findall(addnodes.download_reference)):
            if node.get("reftype") != "myst":
                continue
            target = self._repository_file(node)
            if target is None:
                continue
            anchor = node.get("reftargetid") or ""
            uri = f"{SOURCE_URL}/blob/main/{target}" + (f"#{anchor}" if anchor else "")
            reference = nodes.reference("", "", internal=False, refuri=uri)
            reference += node.children or [nodes.literal(target, target)]
            node.replace_self(reference)

    def _repository_file(self, node: nodes.Element) -> str | None:
        """The repository path the link names, when it is a file outside `docs/` that exists."""
        target = str(node["reftarget"])
        if isinstance(node, addnodes.download_reference):
            base = Path(self.env.doc2path(self.env.docname)).parent
            path = (base / target).resolve()
        elif node.get("refdomain") == "doc" and target not in self.env.all_docs:
            path = (DOCS / f"{target}.md").resolve()  # MyST names a Markdown file outside the source folder like a document
        else:
            return None
        if DOCS in path.parents or REPO not in path.parents or not path.is_file():
            return None
        return path.relative_to(REPO).as_posix()


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_post_transform(RepositoryLinks)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

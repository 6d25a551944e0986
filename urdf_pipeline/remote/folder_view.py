"""Remote files as one local folder, for a reader that wants a dataset's ROOT (Rerun's LeRobotReader): a temporary
folder in which each file, at its path inside the dataset, is a symbolic link to its cached download (urdf-pipeline's
download cache, held while the folder is in use, or the Hub client's cache). Only the files a segment needs are
there; the folder is removed when the block ends, whatever ends it.

The paths come from a stranger's listing and metadata (an S3 key may be `meta/../../x`, a data_path template
`../x`): a path that is absolute, holds an empty, `.` or `..` segment, a backslash or a control character is refused
before anything is linked, so that no link lands outside the folder.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path

from ..errors import UserError, Where, has_control_character, shown
from ..plan import RemoteObject
from .fetching import fetched

NAME_BYTES = 255  # one file name on the file systems a run writes to


def check_relative(path: str, where: Where | None, what: str = "file") -> str:
    """`path` when it names a place inside a folder (segments joined by `/`), else a UserError naming it."""
    parts = path.split("/")
    if (
        not path
        or "\\" in path
        or has_control_character(path)
        or any(part in ("", ".", "..") for part in parts)
        or any(len(part.encode("utf-8", "surrogatepass")) > NAME_BYTES for part in parts)
    ):
        raise UserError(
            f"{what} {shown(path)} does not name a place inside the dataset's folder (an absolute path, an empty, '.' or "
            "'..' segment, a backslash, a control character or a name too long): refused, nothing is read from it",
            where,
        )
    return path


@contextmanager
def fetched_folder(files: Mapping[str, RemoteObject], where: Where | None) -> Iterator[Path]:
    """Each of `files` (its path inside the folder -> the object) fetched as planned and linked at its path in a new
    temporary folder; the folder is removed, and the cache entries released, when the block ends."""
    for relative in files:
        check_relative(relative, where)
    with ExitStack() as held:
        root = Path(held.enter_context(tempfile.TemporaryDirectory(prefix="urdf-pipeline-view-")))
        for relative, remote in sorted(files.items()):
            local = held.enter_context(fetched(remote, where))
            link = root.joinpath(*relative.split("/"))
            try:
                link.parent.mkdir(parents=True, exist_ok=True)
                os.symlink(os.path.realpath(local), link)
            except OSError as exc:  # `meta/x` both a file and a folder: two keys of one listing that cannot both be
                raise UserError(f"cannot place {shown(relative)} of {shown(remote.url)} in a local folder: {exc.strerror}", where) from None
        yield root

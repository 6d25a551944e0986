"""Where outputs bound for S3 are written first: this machine's staging folder, mirroring each bucket
(`ROOT/s3/BUCKET/KEY`), so a recording is written, checked and renamed into place as a local one is, then uploaded.
`URDF_PIPELINE_STAGING` names the folder (default: the user's cache, beside the download cache)."""

from __future__ import annotations

import os
from pathlib import Path

from .locations import RemoteUrl

STAGING_ENV = "URDF_PIPELINE_STAGING"


def staging_root() -> Path:
    named = os.environ.get(STAGING_ENV)
    if named:
        return Path(os.path.abspath(named))
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(os.path.abspath(cache)) / "urdf-pipeline" / "staging"


def staging_folder(bucket: str) -> Path:
    """The folder mirroring `bucket` (a bucket name holds no `/` or `..`: locations.py parsed it)."""
    return staging_root() / "s3" / bucket


def staged_path(url: RemoteUrl) -> Path:
    """Where the object `url` is written before its upload (its key's segments hold no `.`, `..` or empty one)."""
    return staging_folder(url.bucket).joinpath(*url.key.split("/"))

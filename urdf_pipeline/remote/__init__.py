"""Data where teams keep it: `s3://` objects and `hf://` LeRobot datasets, as sources and outputs (docs/remote.md).
The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .download_cache import CACHE_BYTES_ENV, CACHE_ENV, CacheKey, DownloadCache
    from .fetching import cached_metadata, cached_path, download_folder, fetched, remote_file, remote_glob
    from .folder_view import check_relative, fetched_folder
    from .hub import hub_commit, hub_files, hub_snapshot
    from .locations import ALLOW_URLS_ENV, RemoteUrl, check_allowed, is_remote, parse_url, remote_location
    from .s3_objects import OverBudget, download, listing, metadata_of, open_range, upload
    from .staging import STAGING_ENV, staged_path, staging_folder

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)

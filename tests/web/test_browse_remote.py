"""`browse` of a run whose outputs are in S3 (a real moto_server), from a machine that did not run it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from urdf_pipeline.web import ViewerAssets

from ..conftest import S3
from ..dataset_helpers import store_ids


def test_browse_fetches_the_recordings_the_manifest_lists(
    remote_dataset: Path, s3: S3, tmp_path: Path, viewer_cache: ViewerAssets, run_cli
) -> None:
    """`browse` of a run whose outputs are in S3, from another machine (an empty staging folder and cache): the
    manifest from the bucket, each recording the version it recorded, the model and blueprint, all in the site."""
    assert run_cli("run", str(remote_dataset), "--jobs", "2", "-q").code == 0
    shutil.rmtree(tmp_path / "staging")
    site = tmp_path / "site"
    result = run_cli("browse", str(remote_dataset), "-o", str(site))
    assert result.code == 0, result.err
    data = json.loads((site / "segments.json").read_text())
    assert len(data["segments"]) >= 2 and not [s for s in data["segments"] if s.get("missing")]
    assert (site / "recordings" / "shared" / "model.rrd").is_file() and (site / "recordings" / "shared" / "blueprint.rbl").is_file()
    first = data["segments"][0]
    assert store_ids(site / "recordings" / "000000.rrd") == ("so101_dataset", first["id"])

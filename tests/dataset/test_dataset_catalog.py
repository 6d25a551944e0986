"""`run --catalog URL --dataset NAME`: a whole dataset written and registered in a real local Rerun catalog server."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from ..dataset_helpers import isolated_examples

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("allow_examples")]  # configs elsewhere read the session's examples

pytest.importorskip("datafusion", reason="needs the rerun-sdk[catalog] extra (a test dependency)")


@pytest.fixture(scope="module")
def server() -> Iterator[rr.server.Server]:
    with rr.server.Server(host="127.0.0.1", port=0) as server:
        yield server


def test_run_registers_layers_and_model_asset_idempotently(server: rr.server.Server, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "catalog")
    command = ["run", str(config), "--jobs", "2", "--catalog", server.url(), "--dataset", "so101", "--episodes", "0:3"]
    result = run_cli(*command)
    assert result.code == 0, result.err
    assert "dataset 'so101' (created), layer 'urdf': 3 segments added" in result.err

    client = server.client()
    dataset = client.get_dataset("so101")
    segments = [f"episode_{e:06d}" for e in range(3)]
    assert sorted(dataset.segment_ids()) == segments
    assert sorted(dataset.layer("urdf").segment_ids()) == segments
    assert dataset.assets() == ["urdf_model"]
    urls = dataset.segment_table().select("rerun_segment_id", "rerun_storage_urls").to_pydict()
    out = config.parent / "out" / "so101_dataset"
    assert dict(zip(urls["rerun_segment_id"], urls["rerun_storage_urls"], strict=True)) == {
        s: [(out / f"{s}.rrd").resolve().as_uri()] for s in segments
    }

    table = dataset.filter_segments("episode_000001").reader(index="frame_index").to_arrow_table().sort_by("frame_index")
    assert table.num_rows == 150  # the examples' episode 1
    assert np.unique(table.column("frame_index").to_numpy()).tolist() == list(range(150))
    # The dataframe view holds one row per frame_index (the latest of that frame's joint transforms).
    child_frames = table.column("/so101/joint_transforms:Transform3D:child_frame").to_pylist()
    translations = table.column("/so101/joint_transforms:Transform3D:translation").to_pylist()
    assert all(row and row[0] for row in child_frames) and all(row and len(row[0]) == 3 for row in translations)

    again = run_cli(*command)  # a re-run skips every file and registers them again: nothing duplicated
    assert again.code == 0, again.err
    assert "0 segments added, 3 re-registered" in again.err
    assert sorted(client.get_dataset("so101").segment_ids()) == segments
    assert client.get_dataset("so101").assets() == ["urdf_model"]


def test_catalog_needs_a_dataset_name(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "no_dataset")
    result = run_cli("run", str(config), "--catalog", "rerun+http://127.0.0.1:1")
    assert result.code == 1 and "--catalog needs --dataset NAME" in result.err
    assert not (config.parent / "out").exists(), "refused before writing anything"

"""Catalog registration against a real local Rerun server (needs the rerun-sdk[catalog] extra: no skip without it)."""

from __future__ import annotations

import os
import socket
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from rerun.catalog import CatalogClient, DatasetEntry
from rerun.chunk import Chunk, LazyChunkStream

from urdf_pipeline.dataset.catalog import register_in_catalog
from urdf_pipeline.errors import UserError

pytestmark = pytest.mark.slow  # a real Ray cluster or catalog server

SEGMENTS = ("ep0", "ep1", "ep2")
ENTITY = "/robot/joint_transforms"


@pytest.fixture(scope="module")
def server() -> Iterator[rr.server.Server]:
    with rr.server.Server(host="127.0.0.1", port=0) as server:  # in memory, no data directory; shut down on exit
        yield server


@pytest.fixture(scope="module")
def client(server: rr.server.Server) -> CatalogClient:
    return server.client()


def write_rrd(path: Path, recording_id: str, chunks: list[Chunk]) -> Path:
    """Beside the target, then renamed: how the pipeline's writer replaces an output."""
    partial = path.with_name(f".{path.name}.partial")
    LazyChunkStream.from_iter(chunks).write_rrd(partial, application_id="catalog_test", recording_id=recording_id)
    os.replace(partial, path)
    return path


def static_model() -> Chunk:
    return Chunk.from_columns("/robot/base", indexes=[], columns=rr.Boxes3D.columns(half_sizes=[[0.1, 0.2, 0.3]]))


def transforms(frames: int, offset: float) -> Chunk:
    translation = np.column_stack([np.arange(frames), np.full(frames, offset), np.zeros(frames)])
    return Chunk.from_columns(
        ENTITY,
        indexes=[rr.TimeColumn("frame_index", sequence=np.arange(frames))],
        columns=rr.Transform3D.columns(translation=translation, parent_frame=["base"] * frames, child_frame=["link1"] * frames),
    )


@pytest.fixture
def model(tmp_path: Path) -> Path:
    return write_rrd(tmp_path / "model.rrd", "urdf_model", [static_model()])


@pytest.fixture
def layers(tmp_path: Path) -> list[tuple[str, Path]]:
    return [(segment, write_rrd(tmp_path / f"{segment}.rrd", segment, [transforms(5, i)])) for i, segment in enumerate(SEGMENTS)]


def rows(dataset: DatasetEntry, segment: str) -> tuple[list[int], list[list[list[float]]]]:
    table = dataset.filter_segments(segment).reader(index="frame_index").to_arrow_table().sort_by("frame_index")
    return table.column("frame_index").to_pylist(), table.column(f"{ENTITY}:Transform3D:translation").to_pylist()


def storage(dataset: DatasetEntry) -> dict[str, list[tuple[str, str]]]:
    table = dataset.segment_table().select("rerun_segment_id", "rerun_layer_names", "rerun_storage_urls").to_pydict()
    return {s: sorted(zip(n, u, strict=True)) for s, n, u in zip(*table.values(), strict=True)}


def test_registers_segments_under_the_layer_and_the_model_as_asset(
    server: rr.server.Server, client: CatalogClient, model: Path, layers: list[tuple[str, Path]]
) -> None:
    report = register_in_catalog(server.url(), "first", "urdf", model, layers)
    assert (report.dataset_created, report.added, report.replaced) == (True, SEGMENTS, ())
    assert (report.asset, report.asset_replaced) == ("urdf_model", False)
    assert "3 segments added" in report.summary()

    dataset = client.get_dataset("first")
    assert sorted(dataset.segment_ids()) == list(SEGMENTS)
    assert sorted(dataset.layer("urdf").segment_ids()) == list(SEGMENTS)
    assert storage(dataset) == {segment: [("urdf", path.resolve().as_uri())] for segment, path in layers}
    assert dataset.assets() == ["urdf_model"]
    assert dataset.assets_for_segment("ep1") == ["urdf_model"]
    # a segment holding only a non-`base` layer is queried like any other
    frames, translations = rows(dataset, "ep1")
    assert frames == [0, 1, 2, 3, 4]
    assert translations == [[[float(i), 1.0, 0.0]] for i in range(5)]


def test_second_registration_changes_nothing(
    server: rr.server.Server, client: CatalogClient, model: Path, layers: list[tuple[str, Path]]
) -> None:
    register_in_catalog(server.url(), "twice", "urdf", model, layers)
    dataset = client.get_dataset("twice")
    before = storage(dataset)

    report = register_in_catalog(server.url(), "twice", "urdf", model, layers)
    assert (report.dataset_created, report.added, report.replaced) == (False, (), SEGMENTS)
    assert (report.asset, report.asset_replaced) == ("urdf_model", True)
    assert client.dataset_names().count("twice") == 1
    assert storage(dataset) == before
    assert dataset.assets() == ["urdf_model"]
    assert rows(dataset, "ep0")[0] == [0, 1, 2, 3, 4]


def test_rewritten_file_and_new_segment_are_picked_up(
    server: rr.server.Server, client: CatalogClient, tmp_path: Path, layers: list[tuple[str, Path]]
) -> None:
    """The server indexes a file when it is registered: a rewritten file must be registered again (replaced)."""
    register_in_catalog(server.url(), "rewritten", "urdf", None, layers[:2])
    write_rrd(layers[0][1], "ep0", [transforms(8, 7.0)])
    report = register_in_catalog(server.url(), "rewritten", "urdf", None, layers)
    assert (report.added, report.replaced, report.asset) == (("ep2",), ("ep0", "ep1"), None)
    frames, translations = rows(client.get_dataset("rewritten"), "ep0")
    assert frames == list(range(8))
    assert translations[-1] == [[7.0, 7.0, 0.0]]


def test_asset_with_temporal_chunks_is_refused(server: rr.server.Server, client: CatalogClient, tmp_path: Path) -> None:
    moving = write_rrd(tmp_path / "moving_model.rrd", "urdf_model", [static_model(), transforms(3, 0.0)])
    with pytest.raises(UserError, match=r"moving_model\.rrd.*temporal chunks.*static"):
        register_in_catalog(server.url(), "temporal_asset", "urdf", moving, [])
    assert client.get_dataset("temporal_asset").assets() == []


def test_unreachable_server_is_a_user_error(model: Path, layers: list[tuple[str, Path]]) -> None:
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with pytest.raises(UserError, match=rf"cannot reach the catalog server at rerun\+http://127\.0\.0\.1:{port}"):
        register_in_catalog(f"http://127.0.0.1:{port}", "unreachable", "urdf", model, layers)


def test_malformed_url_is_a_user_error(model: Path) -> None:
    with pytest.raises(UserError, match=r"'catalog-host:51234' is not a catalog URL.*rerun\+http://"):
        register_in_catalog("catalog-host:51234", "bad_url", "urdf", model, [])


def test_missing_catalog_extra_names_the_install(monkeypatch: pytest.MonkeyPatch, server: rr.server.Server, model: Path) -> None:
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "datafusion" else find_spec(name, *a))
    with pytest.raises(UserError, match=r"pip install 'rerun-sdk\[catalog\]==0\.41\.\*'"):
        register_in_catalog(server.url(), "no_extra", "urdf", model, [])


def test_missing_file_is_refused_before_contacting_the_server(tmp_path: Path, model: Path) -> None:
    with pytest.raises(UserError, match=r"missing recordings.*ep7\.rrd"):
        register_in_catalog("rerun+http://127.0.0.1:9", "missing", "urdf", model, [("ep7", tmp_path / "ep7.rrd")])


def test_file_of_another_recording_is_reported(server: rr.server.Server, tmp_path: Path) -> None:
    other = write_rrd(tmp_path / "ep5.rrd", "ep6", [transforms(2, 0.0)])
    with pytest.raises(UserError, match=r"ep5\.rrd holds recording 'ep6', not 'ep5'"):
        register_in_catalog(server.url(), "mismatch", "urdf", None, [("ep5", other)])

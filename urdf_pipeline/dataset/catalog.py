"""Register a run's recordings in a Rerun catalog server: layers per segment, the model as a dataset asset.

The server reads the files itself (`file://` URIs), indexes them when they are registered and reads their
chunks again at query time: the files must stay where they are, and a rewritten file must be registered again.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import UserError, listing

if TYPE_CHECKING:
    from rerun.catalog import CatalogClient, DatasetEntry

EXTRA = "rerun-sdk[catalog]==0.41.*"


@dataclass(frozen=True)
class CatalogReport:
    """What one registration did, for the CLI's one-line summary."""

    url: str
    dataset: str
    layer: str
    dataset_created: bool
    added: tuple[str, ...]  # segments that did not have the layer yet
    replaced: tuple[str, ...]  # segments that had it: registered again, as their file may have been rewritten
    asset: str | None  # the model's asset id (its recording id), None without a model
    asset_replaced: bool = False  # the asset was already there (registering it again replaces it)

    def summary(self) -> str:
        created = " (created)" if self.dataset_created else ""
        line = f"catalog {self.url}: dataset {self.dataset!r}{created}, layer {self.layer!r}: {len(self.added)} segments added, {len(self.replaced)} re-registered"
        if self.asset is not None:
            line += f"; model asset {self.asset!r} {'re-registered' if self.asset_replaced else 'added'}"
        return line


def register_in_catalog(
    url: str, dataset: str, layer: str, model: Path | str | None, layers: Sequence[tuple[str, Path | str]]
) -> CatalogReport:
    """Create (or reuse) `dataset`, register `model` as its asset and each (segment id, .rrd) under `layer`.

    Re-running is safe: layers already present are replaced (the server would otherwise keep indexing the old
    bytes of a rewritten file, or refuse the duplicate), and an asset with the same recording id is replaced.
    """
    _check_inputs(model, layers)
    url = _normalized(url)
    client = _connect(url)
    with _refusals(url, f"dataset {dataset!r}"):
        created = dataset not in client.dataset_names()
        entry = client.create_dataset(dataset, exist_ok=True)
    asset, asset_replaced = (None, False) if model is None else _register_model(entry, url, model)
    added, replaced = _register_layers(entry, url, layer, layers) if layers else ((), ())
    return CatalogReport(url, dataset, layer, created, added, replaced, asset, asset_replaced)


def _uri(recording: Path | str) -> str:
    """A local recording as a `file://` URI; an output in S3 is given as its `s3://` URL (a catalog that reads S3
    takes it; Rerun's open-source `rerun server` reads local files only, and refuses it by name)."""
    return recording if isinstance(recording, str) else recording.resolve().as_uri()


def _check_inputs(model: Path | str | None, layers: Sequence[tuple[str, Path | str]]) -> None:
    """Refuse before contacting the server: a missing file or a repeated segment rejects the whole batch there."""
    local = [path for path in ([model] if model else []) + [path for _, path in layers] if isinstance(path, Path)]
    missing = [str(path) for path in local if not path.is_file()]
    if missing:
        raise UserError(f"cannot register missing recordings in the catalog: {listing(missing)}; run the dataset first", None)
    ids = [segment for segment, _ in layers]
    repeated = sorted({segment for segment in ids if ids.count(segment) > 1})
    if repeated:
        raise UserError(f"segments given more than one file for the same catalog layer: {listing(repeated)}", None)


def _normalized(url: str) -> str:
    """`http://` is what users type; the SDK wants `rerun+http://` (it would rewrite it too, with a warning)."""
    return f"rerun+{url}" if url.startswith(("http://", "https://")) else url


def _connect(url: str) -> CatalogClient:
    """The client connects on construction: an unreachable server and a missing extra both show here."""
    try:
        from rerun.catalog import CatalogClient

        return CatalogClient(url)
    except ImportError as exc:  # no datafusion, or one of the wrong major version
        raise UserError(f"registering in a catalog needs the catalog extra: pip install '{EXTRA}' ({exc})", None) from None
    except ConnectionError as exc:
        raise UserError(
            f"cannot reach the catalog server at {url}: {_server_says(exc)}; start it (`rerun server`) or fix the URL", None
        ) from None
    except ValueError as exc:
        raise UserError(f"{url!r} is not a catalog URL ({exc}); expected e.g. rerun+http://127.0.0.1:51234", None) from None


def _register_model(entry: DatasetEntry, url: str, model: Path | str) -> tuple[str, bool]:
    """The asset id is the file's recording id, so registering the same model again replaces it."""
    try:
        with _refusals(url, f"model asset {model}"):
            before = set(entry.assets())
            asset = entry.register_asset(_uri(model))
    except UserError as exc:
        if "only accept static" not in exc.message:
            raise
        raise UserError(
            f"the catalog refuses {model} as a dataset asset: it holds temporal chunks, and an asset must be static only; "
            "write the model without time (static=True) and its motion into the segments' layers",
            None,
        ) from None
    return asset, asset in before


def _register_layers(
    entry: DatasetEntry, url: str, layer: str, layers: Sequence[tuple[str, Path | str]]
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """One batch call with on_duplicate=REPLACE: fast for hundreds of files, and re-runs pick up rewritten files."""
    from rerun.catalog import OnDuplicateSegmentLayer

    expected = [segment for segment, _ in layers]
    with _refusals(url, f"layer {layer!r} of {len(layers)} recordings"):
        present = _segments_with_layer(entry, layer)
        operation = entry.register([_uri(path) for _, path in layers], layer_name=layer, on_duplicate=OnDuplicateSegmentLayer.REPLACE)
        registered = operation.wait().segment_ids
    wrong = [f"{path} holds recording {got!r}, not {want!r}" for (want, path), got in zip(layers, registered, strict=True) if got != want]
    if wrong:
        raise UserError(
            f"recordings registered under the wrong segment (the server takes a file's recording id as its segment id): {listing(wrong, separator='; ')}; "
            "rewrite them with the right recording id, and drop the stray segments (dataset.segment(id).delete_layer(layer))",
            None,
        )
    return tuple(s for s in expected if s not in present), tuple(s for s in expected if s in present)


def _segments_with_layer(entry: DatasetEntry, layer: str) -> set[str]:
    table = entry.segment_table().select("rerun_segment_id", "rerun_layer_names").to_pydict()
    return {segment for segment, names in zip(table["rerun_segment_id"], table["rerun_layer_names"], strict=True) if layer in names}


@contextmanager
def _refusals(url: str, what: str) -> Iterator[None]:
    """Server-side refusals (unreadable file, bad name, lost connection) become one-line user errors."""
    from rerun.catalog import AlreadyExistsError, NotFoundError

    try:
        yield
    except (ValueError, OSError, NotFoundError, AlreadyExistsError) as exc:  # OSError covers ConnectionError, TimeoutError
        raise UserError(f"catalog server at {url} refused {what}: {_server_says(exc)}", None) from None


def _server_says(exc: BaseException) -> str:
    """The server's message without its trace ids, endpoint and gRPC metadata lines."""
    noise = ("- Server:", "- Endpoint:", "- trace-id:", "- metadata:", "Registration request trace-id", "Task-completion query trace-id")
    lines = [line.strip() for line in str(exc).splitlines()]
    return " ".join(line for line in lines if line not in ("", "-") and not line.startswith(noise))

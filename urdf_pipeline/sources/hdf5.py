"""A 2-D HDF5 dataset [rows, values] (e.g. ALOHA's /observations/qpos), read with Rerun's Hdf5Reader. Validation reads
metadata with h5py (of a remote file, through bounded ranged GETs: see `_compile_remote`), then of a local file the
values; at run time every other dataset of the file (camera images, ...) is ignored, so only these two are loaded.
"""

from __future__ import annotations

import posixpath
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any

from ..config import Document
from ..errors import UserError, Where, listing
from ..plan import Hdf5SourcePlan, IndexPlan
from ..remote import is_remote
from .base import EntryField, SourceDescription, file_input, resolve_input, rooted, shown_file
from .integrity import HDF5_BLOCK_ROWS, check_hdf5_datasets, hdf5_file_problem, hdf5_storage_problem
from .ordering import in_blocks, in_time_order, with_duplicates
from .stream import SourceStream, compile_index, index_column
from .time_range import check_index_batches

PLAN_TYPE = Hdf5SourcePlan
SPEC_FORM = "hdf5:FILE#/DATASET"
SUFFIXES = (".h5", ".hdf5")
REMOTE_BLOCK = 256 << 10  # bytes a ranged GET fetches at least, reading an S3 file's structure ...
REMOTE_REQUESTS = 32  # ... and how many it may take before the file is downloaded instead (see _compile_remote)


def _datasets_of_rank(file: Any, rank: int) -> list[str]:
    import h5py

    found: list[str] = []
    file.visititems(lambda name, node: found.append("/" + name) if isinstance(node, h5py.Dataset) and node.ndim == rank else None)
    return found


@dataclass(frozen=True)
class _Named:
    """The file as messages name it: its path, or its URL (`shown`), its name alone, and its size in bytes."""

    shown: str
    name: str
    size: int


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> Hdf5SourcePlan:
    here = ("sources", name)
    if is_remote(spec["hdf5"]):
        return _compile_remote(name, spec, document)
    path = resolve_input(document, config_dir, spec["hdf5"], *here, "hdf5")
    named = _Named(str(path), path.name, path.stat().st_size)
    with _opened(path, named, document.where(*here, "hdf5")) as file:
        plan = _compiled(file, named, path, name, spec, document)
    _check_values(plan, named, document.where(*here, "hdf5"), document.where(*here, "index"))
    return plan


def _check_values(plan: Hdf5SourcePlan, named: _Named, where: Where, index_where: Where) -> None:
    """What only the values tell: the index's times fit a timeline, and every chunk of the two datasets decodes (a
    corrupt one is a user error here, not a RuntimeError inside Rerun's reader)."""
    if plan.index is not None:
        with _opened(plan.path, named, where) as file:
            _check_index_values(file[plan.index.column], plan.index, plan.rows, named, index_where)
    check_hdf5_datasets(plan.path, [plan.dataset, *([plan.index.column] if plan.index is not None else [])], where, named.shown)


def _opened(source: Path | IO[bytes], named: _Named, where: Where) -> Any:
    import h5py

    try:
        return h5py.File(source, "r")
    except OSError as exc:
        raise UserError(f"cannot open HDF5 file {named.shown}: {exc}", where) from None


def _compile_remote(name: str, spec: dict[str, Any], document: Document) -> Hdf5SourcePlan:
    """`hdf5: s3://BUCKET/KEY`: h5py reads the structure through at most REMOTE_REQUESTS ranged GETs, else the file is
    downloaded into the cache now, as `run` would, and read locally; the values are checked by `check_download`."""
    from ..remote import OverBudget, cached_path, fetched, open_range, remote_file

    where = document.where("sources", name, "hdf5")
    remote = remote_file(spec["hdf5"], where, "hdf5 file")
    named = _Named(remote.url, remote.url.rsplit("/", 1)[-1], remote.size)
    try:
        with open_range(remote, where, block=REMOTE_BLOCK, max_requests=REMOTE_REQUESTS) as reader, _opened(reader, named, where) as file:
            plan = _compiled(file, named, cached_path(remote), name, spec, document)
    except OverBudget:
        with fetched(remote, where) as local, _opened(local, named, where) as file:
            plan = _compiled(file, named, local, name, spec, document)
    return replace(plan, remote=remote)


def check_download(plan: Hdf5SourcePlan) -> None:
    """A remote file's values, once `run` has downloaded it to `plan.path` (compile read its structure only)."""
    shown = shown_file(plan)
    _check_values(plan, _Named(shown, shown.rsplit("/", 1)[-1], plan.path.stat().st_size), plan.where, plan.where)


def _compiled(file: Any, named: _Named, path: Path, name: str, spec: dict[str, Any], document: Document) -> Hdf5SourcePlan:
    """The plan from the open file's structure alone (no value is read): the dataset and the index exist, have the
    shapes and types a joint source needs, and the file stores their bytes."""
    import h5py

    here = ("sources", name)
    dataset = rooted(spec["dataset"])
    names: tuple[str, ...] | None = tuple(spec["names"]) if "names" in spec else None
    index: IndexPlan | None = None
    if "index" in spec:
        parsed = compile_index(spec["index"])
        index = IndexPlan(rooted(parsed.column), parsed.kind, parsed.unit)
    problem = hdf5_file_problem(file)
    if problem is not None:
        raise UserError(f"HDF5 file {named.shown} {problem}", document.where(*here, "hdf5"))
    node = _node(file, dataset, named, document.where(*here, "dataset"))
    if not isinstance(node, h5py.Dataset):
        raise UserError(
            f"no dataset '{dataset}' in {named.name}; its 2-D datasets: {listing(_datasets_of_rank(file, 2), empty='none')}",
            document.where(*here, "dataset"),
        )
    if node.ndim != 2:
        raise UserError(
            f"dataset '{dataset}' has shape {list(node.shape)}; a joint source needs [rows, values] (2-D)", document.where(*here, "dataset")
        )
    if node.dtype.kind not in "fiu":
        raise UserError(f"dataset '{dataset}' holds {node.dtype}, not numbers", document.where(*here, "dataset"))
    _require_stored(node, dataset, named, document.where(*here, "dataset"))
    rows, width = node.shape
    if names is None:  # no names: the values are mapped by their index, 0 .. width - 1
        names = tuple(str(i) for i in range(width))
    if width != len(names):
        raise UserError(
            f"dataset '{dataset}' holds {width} values per row but {len(names)} names are given", document.where(*here, "names")
        )
    if rows == 0:
        raise UserError(f"dataset '{dataset}' of {named.shown} has zero rows; nothing would move", document.where(*here, "dataset"))
    if index is not None:
        _check_index(file, index, rows, named, document.where(*here, "index"))
    return with_duplicates(Hdf5SourcePlan(name, path, dataset, index, rows, names, document.where(*here)), spec)


def _check_index(file: Any, index: IndexPlan, rows: int, named: _Named, where: Where) -> None:
    """The index dataset's structure: 1-D, one value per row, numbers a timeline of its kind holds."""
    import h5py

    node = _node(file, index.column, named, where)
    if not isinstance(node, h5py.Dataset):
        raise UserError(
            f"no index dataset '{index.column}' in {named.name}; its 1-D datasets: {listing(_datasets_of_rank(file, 1), empty='none')}",
            where,
        )
    if node.ndim != 1:
        raise UserError(f"index dataset '{index.column}' has shape {list(node.shape)}; an index is 1-D, one value per row", where)
    if len(node) != rows:
        raise UserError(f"index dataset '{index.column}' has {len(node)} values but the joint dataset has {rows} rows", where)
    if index.kind == "sequence" and node.dtype.kind not in "iu":
        raise UserError(
            f"index dataset '{index.column}' holds {node.dtype}; a sequence timeline needs integers (use {{timestamp: {index.column}, unit: s}} for times)",
            where,
        )
    if node.dtype.kind not in "fiu":
        raise UserError(f"index dataset '{index.column}' holds {node.dtype}, not a time", where)
    _require_stored(node, index.column, named, where)


def _check_index_values(node: Any, index: IndexPlan, rows: int, named: _Named, where: Where) -> None:
    """The index's values, a block of rows at a time: times a timeline can hold."""
    blocks = (node[start : start + HDF5_BLOCK_ROWS] for start in range(0, rows, HDF5_BLOCK_ROWS))  # one per block of rows
    try:
        check_index_batches(blocks, index, f"index dataset '{index.column}' of {named.name}", where)
    except (OSError, ValueError, RuntimeError) as exc:  # a corrupt chunk: check_hdf5_datasets names it too
        raise UserError(f"HDF5 file {named.shown} is corrupt: index dataset '{index.column}' cannot be read: {exc}", where) from None


def _node(file: Any, name: str, named: _Named, where: Where) -> Any:
    """The object at `name`, or None; a link that cannot be followed (a soft link to itself) is a user error."""
    try:
        return file.get(name)
    except (KeyError, OSError, RuntimeError, ValueError) as exc:
        raise UserError(f"'{name}' in HDF5 file {named.shown} cannot be opened: {str(exc).strip() or type(exc).__name__}", where) from None


def _require_stored(node: Any, name: str, named: _Named, where: Where) -> None:
    """Before any value is read (by the checks, or by Rerun at run): the file holds the dataset's bytes."""
    problem = hdf5_storage_problem(node, named.size)
    if problem is not None:
        raise UserError(f"dataset '{name}' of HDF5 file {named.name} {problem}", where)


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the width of the 2-D dataset PART names, as `validate` reads its shape. HDF5 has no names: the
    values are matched by position."""
    given = file_input(path)
    dataset = rooted(part or "/")
    try:
        plan = compile_source(name, {"hdf5": str(given.file), "dataset": dataset}, document, given.file.parent)
    except UserError as exc:
        raise UserError(exc.message + ("; name it with hdf5:FILE#/DATASET" if part is None else "")) from None
    note = "index: /DATASET  (optional: a 1-D dataset of times or frame numbers; default a row_index sequence)"
    fields = (EntryField("dataset", dataset),)
    return SourceDescription(
        "hdf5", fields, None, len(plan.names), given.segment, pattern=given.pattern, unnamed="HDF5 carries no names", notes=(note,)
    )


def open_stream(plan: Hdf5SourcePlan) -> SourceStream:
    from rerun.experimental import Hdf5Reader

    reader = Hdf5Reader(plan.path)
    keep = {plan.dataset} | ({plan.index.column} if plan.index is not None else set())
    ignored = [info.path for info in reader.datasets() if info.path not in keep]
    group, component = posixpath.split(plan.dataset)  # Rerun's Hdf5Reader: a group is an entity, its datasets components
    entity = group or "/"
    stream = reader.stream(
        index_column=index_column(plan.index) if plan.index is not None else None,
        ignore_datasets=ignored or None,
        use_structs=False,
    ).filter(content=entity, is_static=False, components=component)
    if plan.index is not None:  # without an index, Rerun numbers the rows: nothing to check, only blocks to make
        stream = in_time_order(stream, plan.index.column, plan, shown_file(plan))
    else:
        stream = in_blocks(stream)
    return SourceStream(stream, entity, component, len(plan.names))

"""A 2-D HDF5 dataset [rows, values] (e.g. ALOHA's /observations/qpos, both arms in one vector), read with Rerun's Hdf5Reader.

Validation opens the file with h5py and reads metadata only: the dataset's shape and type, the index dataset's.
At run time every other dataset of the file (camera images, ...) is ignored, so only these two are loaded.
"""

from __future__ import annotations

import posixpath
from pathlib import Path
from typing import Any

from ..config import Document
from ..errors import UserError, Where, listing
from ..plan import Hdf5SourcePlan, IndexPlan
from .base import EntryField, SourceDescription, file_input, no_remote_files, resolve_input
from .integrity import HDF5_BLOCK_ROWS, check_hdf5_datasets, hdf5_file_problem, hdf5_storage_problem
from .ordering import in_blocks, in_time_order, with_duplicates
from .stream import SourceStream, compile_index, index_column
from .time_range import check_index_batches

check_download = no_remote_files
PLAN_TYPE = Hdf5SourcePlan
SPEC_FORM = "hdf5:FILE#/DATASET"
SUFFIXES = (".h5", ".hdf5")


def dataset_path(path: str) -> str:
    return "/" + path.strip("/")


def entity_and_component(dataset: str) -> tuple[str, str]:
    """Rerun's Hdf5Reader: a group becomes an entity, each of its datasets a component named after the dataset."""
    group, leaf = posixpath.split(dataset)
    return group or "/", leaf


def _datasets_of_rank(file: Any, rank: int) -> list[str]:
    import h5py

    found: list[str] = []
    file.visititems(lambda name, node: found.append("/" + name) if isinstance(node, h5py.Dataset) and node.ndim == rank else None)
    return found


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> Hdf5SourcePlan:
    import h5py

    here = ("sources", name)
    path = resolve_input(document, config_dir, spec["hdf5"], *here, "hdf5")
    dataset = dataset_path(spec["dataset"])
    names: tuple[str, ...] | None = tuple(spec["names"]) if "names" in spec else None
    index: IndexPlan | None = None
    if "index" in spec:
        parsed = compile_index(spec["index"])
        index = IndexPlan(dataset_path(parsed.column), parsed.kind, parsed.unit)
    try:
        file = h5py.File(path, "r")
    except OSError as exc:
        raise UserError(f"cannot open HDF5 file {path}: {exc}", document.where(*here, "hdf5")) from None
    with file:
        problem = hdf5_file_problem(file)
        if problem is not None:
            raise UserError(f"HDF5 file {path} {problem}", document.where(*here, "hdf5"))
        node = _node(file, dataset, path, document.where(*here, "dataset"))
        if not isinstance(node, h5py.Dataset):
            raise UserError(
                f"no dataset '{dataset}' in {path.name}; its 2-D datasets: {listing(_datasets_of_rank(file, 2), empty='none')}",
                document.where(*here, "dataset"),
            )
        if node.ndim != 2:
            raise UserError(
                f"dataset '{dataset}' has shape {list(node.shape)}; a joint source needs [rows, values] (2-D)",
                document.where(*here, "dataset"),
            )
        if node.dtype.kind not in "fiu":
            raise UserError(f"dataset '{dataset}' holds {node.dtype}, not numbers", document.where(*here, "dataset"))
        _require_stored(node, dataset, path, document.where(*here, "dataset"))
        rows, width = node.shape
        if names is None:  # no names: the values are mapped by their index, 0 .. width - 1
            names = tuple(str(i) for i in range(width))
        if width != len(names):
            raise UserError(
                f"dataset '{dataset}' holds {width} values per row but {len(names)} names are given", document.where(*here, "names")
            )
        if rows == 0:
            raise UserError(f"dataset '{dataset}' of {path} has zero rows; nothing would move", document.where(*here, "dataset"))
        if index is not None:
            _check_index(file, index, rows, path, document, here)
    # Every chunk decodes (a corrupt one is a user error here, not a RuntimeError inside Rerun's reader).
    check_hdf5_datasets(path, [dataset, *([index.column] if index is not None else [])], document.where(*here, "hdf5"))
    return with_duplicates(Hdf5SourcePlan(name, path, dataset, index, rows, names, document.where(*here)), spec)


def _check_index(file: Any, index: IndexPlan, rows: int, path: Path, document: Document, here: tuple[str, str]) -> None:
    import h5py

    where = document.where(*here, "index")
    node = _node(file, index.column, path, where)
    if not isinstance(node, h5py.Dataset):
        raise UserError(
            f"no index dataset '{index.column}' in {path.name}; its 1-D datasets: {listing(_datasets_of_rank(file, 1), empty='none')}",
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
    _require_stored(node, index.column, path, where)
    blocks = (node[start : start + HDF5_BLOCK_ROWS] for start in range(0, rows, HDF5_BLOCK_ROWS))  # one per block of rows
    try:
        check_index_batches(blocks, index, f"index dataset '{index.column}' of {path.name}", where)
    except (OSError, ValueError, RuntimeError) as exc:  # a corrupt chunk: check_hdf5_datasets names it too
        raise UserError(f"HDF5 file {path} is corrupt: index dataset '{index.column}' cannot be read: {exc}", where) from None


def _node(file: Any, name: str, path: Path, where: Where) -> Any:
    """The object at `name`, or None; a link that cannot be followed (a soft link to itself) is a user error."""
    try:
        return file.get(name)
    except (KeyError, OSError, RuntimeError, ValueError) as exc:
        raise UserError(f"'{name}' in HDF5 file {path} cannot be opened: {str(exc).strip() or type(exc).__name__}", where) from None


def _require_stored(node: Any, name: str, path: Path, where: Where) -> None:
    """Before any value is read (by the checks, or by Rerun at run): the file holds the dataset's bytes."""
    problem = hdf5_storage_problem(node, path.stat().st_size)
    if problem is not None:
        raise UserError(f"dataset '{name}' of HDF5 file {path.name} {problem}", where)


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the width of the 2-D dataset PART names, as `validate` reads its shape. HDF5 has no names: the
    values are matched by position."""
    given = file_input(path)
    dataset = dataset_path(part or "/")
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
    entity, component = entity_and_component(plan.dataset)
    stream = reader.stream(
        index_column=index_column(plan.index) if plan.index is not None else None,
        ignore_datasets=ignored or None,
        use_structs=False,
    ).filter(content=entity, is_static=False, components=component)
    if plan.index is not None:  # without an index, Rerun numbers the rows: nothing to check, only blocks to make
        stream = in_time_order(stream, plan.index.column, plan, plan.path)
    else:
        stream = in_blocks(stream)
    return SourceStream(stream, entity, component, len(plan.names))

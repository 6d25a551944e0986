"""Data files are checked with pyarrow and h5py before Rerun's native readers see them: a parquet data page that fails
to decompress panics a reader thread (the process aborts, or waits forever), an HDF5 chunk that fails to inflate
surfaces as a bare RuntimeError; pyarrow and h5py raise ordinary exceptions, which become one user error naming the
file and the row group or dataset. (MCAP files are probed in a child process instead: mcap_probe.py.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import UserError, Where
from ..plan import IndexPlan
from .time_range import index_problem


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def refuse_empty_parquet(path: Path, where: Where | None) -> None:
    """A file of zero rows is refused, from the footer alone (no data page is read)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        rows = pq.read_metadata(path).num_rows
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise UserError(f"cannot read the parquet footer of {path}: {_reason(exc)}", where) from None
    if rows == 0:
        raise UserError(f"parquet file {path} has zero rows (its footer says so); a source with zero rows moves nothing", where)


HDF5_BLOCK_ROWS = 65_536  # rows decoded at a time when checking an HDF5 dataset: memory stays bounded


CHECK_BATCH_ROWS = 65_536


def check_parquet_pages(
    path: Path, columns: Sequence[str], where: Where | None, index: IndexPlan | None = None, index_where: Where | None = None
) -> None:
    """Every data page of `columns` decodes (page checksums verified when stored), CHECK_BATCH_ROWS rows at a time
    dropped as they come; a corrupt page names its row group. `index` (one of `columns`): its values are checked in the
    same pass as times a timeline can hold (time_range.py), refused at `index_where` once every page has decoded."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        file = pq.ParquetFile(path, page_checksum_verification=True)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise UserError(f"cannot read parquet file {path}: {_reason(exc)}", where) from None
    groups = file.metadata.num_row_groups
    row, index_problem_found = 0, None
    for group in range(groups):  # one iteration per row group, not per row
        try:
            for batch in file.iter_batches(batch_size=CHECK_BATCH_ROWS, row_groups=[group], columns=list(columns)):
                if index is not None and index_problem_found is None:  # decoded, checked, dropped
                    index_problem_found = index_problem(batch.column(index.column), index, row, f"index column '{index.column}' of {path}")
                row += batch.num_rows
        except (pa.ArrowException, OSError, ValueError) as exc:
            raise UserError(
                f"parquet file {path} is corrupt: row group {group} of {groups} ({', '.join(columns)}) cannot be decoded: "
                f"{_reason(exc)}; re-export or replace the file",
                where,
            ) from None
    if index_problem_found is not None:
        raise UserError(index_problem_found, index_where)


def check_hdf5_datasets(path: Path, datasets: Sequence[str], where: Where | None, shown: str | None = None) -> None:
    """Every chunk of each dataset decodes, HDF5_BLOCK_ROWS rows at a time; a corrupt chunk or a truncated file names
    both the file (`shown`: a remote file's URL; its path by default) and the dataset."""
    import h5py

    shown = shown or str(path)
    try:
        file = h5py.File(path, "r")
    except OSError as exc:
        raise UserError(f"cannot open HDF5 file {shown}: {_reason(exc)}", where) from None
    with file:
        for dataset in datasets:
            try:
                values = file[dataset]
                if not values.shape:
                    _ = values[()]  # decoded and dropped
                for start in range(0, values.shape[0] if values.shape else 0, HDF5_BLOCK_ROWS):  # one per block of rows
                    _ = values[start : start + HDF5_BLOCK_ROWS]  # decoded and dropped
            except (OSError, KeyError, ValueError, RuntimeError) as exc:
                raise UserError(
                    f"HDF5 file {shown} is corrupt: dataset '{dataset}' cannot be read: {_reason(exc)}; re-export or replace the file",
                    where,
                ) from None


# HDF5 declares a dataset's shape apart from what it stores: a file of a few KB can declare 2^34 rows never written
# (read back as zeros). A dataset is read only when the file holds its bytes: every chunk allocated, a contiguous block
# inside the file, and beyond HDF5_FREE_BYTES declared at most HDF5_MAX_RATIO times fewer bytes stored than declared
# (an idle recording packs ~1000:1 with deflate: let through while small). So a file's work is bounded by its size.
HDF5_MAX_RATIO = 100
HDF5_FREE_BYTES = 64 << 20


def hdf5_file_problem(file: Any) -> str | None:
    """Why the open h5py `file` is not read at all: an external link anywhere in it (opening it, h5py or Rerun's
    reader would open another file, outside the config's roots and unchecked); None when there is none."""
    import h5py

    def external(name: str, link: Any) -> str | None:
        return f"/{name}" if isinstance(link, h5py.ExternalLink) else None

    found = file.visititems_links(external)
    return f"holds an external link ({found}), which reads another file; copy the data into this file" if found else None


def hdf5_storage_problem(node: Any, file_size: int) -> str | None:
    """Why the h5py dataset `node` is not read: its values live in other files (virtual, external storage), or the
    file stores far fewer bytes than its shape declares; None when it holds them. Metadata only, constant time."""
    import h5py

    plist = node.id.get_create_plist()
    layout = plist.get_layout()
    if layout == h5py.h5d.VIRTUAL:
        return "is a virtual dataset (its values are read from other files); copy the data into this file"
    if plist.get_external_count():
        return "keeps its values in external raw files, which a config may not make the tool read; copy the data into this file"
    declared = int(node.size) * node.dtype.itemsize
    if declared == 0:
        return None
    stored = int(node.id.get_storage_size())
    rows = node.shape[0] if node.shape else 1
    says = f"declares {rows} rows ({declared} bytes) but the file stores {stored} bytes of it"
    fix = "write the dataset fully, or cut it to the rows written"
    if layout == h5py.h5d.CHUNKED:
        needed = math.prod(-(-size // chunk) for size, chunk in zip(node.shape, node.chunks, strict=True))
        allocated = int(node.id.get_num_chunks())
        if allocated < needed:
            return f"{says} ({allocated} of its {needed} chunks were written; the others would read as fill values, not data); {fix}"
    elif layout == h5py.h5d.CONTIGUOUS:
        offset = node.id.get_offset()
        if stored < declared or offset is None or offset + declared > file_size:
            return f"{says}{'' if offset is None else f' at offset {offset} of a {file_size}-byte file'}; {fix}"
    if declared > HDF5_FREE_BYTES and stored * HDF5_MAX_RATIO < declared:
        return (
            f"{says}: more than {HDF5_MAX_RATIO} times less than declared, far beyond what logged joint values compress to "
            f"(a decompression bomb, or a constant signal); {fix}"
        )
    return None

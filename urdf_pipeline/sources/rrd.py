"""Joint values already in a Rerun recording (.rrd): one component of one entity, read with Rerun's RrdReader.

Validation reads the recording's manifest and, for names, the entity's static `SeriesLines:names` (as Rerun's LeRobot
importer writes it), else per-row names (as its MCAP importer writes them), mapped row by row. Rerun's reader opens
local files only: a remote recording is downloaded by validation already (`_compile_remote`).
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..config import Document
from ..errors import UserError, Where
from ..plan import RrdSourcePlan
from ..remote import is_remote
from .base import EntryField, SourceDescription, file_input, resolve_input, rooted, shown_file
from .lerobot import VECTOR_COMPONENT
from .named_rows import NAMED_COMPONENT, named_rows_column
from .ordering import in_time_order, read_all, with_duplicates
from .stream import SourceStream, component_field, is_list_type, per_row

if TYPE_CHECKING:
    from rerun.chunk import Chunk, LazyStore

PLAN_TYPE = RrdSourcePlan
SPEC_FORM = "rrd:FILE#ENTITY"
SUFFIXES = (".rrd",)
NAMES_COMPONENT = "SeriesLines:names"
DEFAULT_COMPONENT = "Scalars:scalars"


def _is_number(value_type: pa.DataType) -> bool:
    return pa.types.is_floating(value_type) or pa.types.is_integer(value_type)


def layout_of(column_type: pa.DataType) -> str | None:
    """'scalars': a row's instances are its values (Scalars); 'vector': one instance per row holding all values."""
    if not is_list_type(column_type):
        return None
    instance = column_type.value_type
    if _is_number(instance):
        return "scalars"
    if is_list_type(instance) and _is_number(instance.value_type):
        return "vector"
    return None


def _open_store(path: Path, shown: str, where: Where) -> LazyStore:
    from rerun.chunk import RrdReader

    try:
        return RrdReader(path).store()
    except (ValueError, OSError, RuntimeError) as exc:
        raise UserError(f"cannot read recording {shown}: {exc}", where) from None


def _static_names(store: LazyStore, entity: str) -> tuple[str, ...]:
    names: tuple[str, ...] = ()
    for chunk in store.stream().filter(content=entity, is_static=True, components=NAMES_COMPONENT).to_chunks():
        batch = chunk.to_record_batch()
        column = batch.column(batch.schema.get_field_index(NAMES_COMPONENT))
        for row in reversed(range(len(column))):  # a static component's last row is the one in effect
            if column[row].is_valid:
                names = tuple(column[row].as_py())
                break
    return names


def _first_row_names(store: LazyStore, entity: str) -> tuple[str, ...]:
    for chunk in store.stream().filter(content=entity, is_static=False, components=NAMES_COMPONENT):
        batch = chunk.to_record_batch()
        column = batch.column(batch.schema.get_field_index(NAMES_COMPONENT)).drop_null()
        if len(column):
            return tuple(column[0].as_py())
    return ()


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> RrdSourcePlan:
    here = ("sources", name)
    where = document.where(*here, "rrd")
    if is_remote(spec["rrd"]):
        return _compile_remote(name, spec, document)
    path = resolve_input(document, config_dir, spec["rrd"], *here, "rrd")
    store = _open_store(path, str(path), where)
    plan = _compiled(store, path, path.name, name, spec, document)
    _check_values(store, plan, str(path), where)
    return plan


def _compile_remote(name: str, spec: dict[str, Any], document: Document) -> RrdSourcePlan:
    """`rrd: s3://BUCKET/KEY`: downloaded into the cache now (Rerun's reader opens local files only; `run` finds it
    there) and read as a local one; its values are checked by `check_download`."""
    from ..remote import fetched, remote_file

    where = document.where("sources", name, "rrd")
    remote = remote_file(spec["rrd"], where, "rrd file")
    with fetched(remote, where) as path:
        plan = _compiled(_open_store(path, remote.url, where), path, remote.url.rsplit("/", 1)[-1], name, spec, document)
    return replace(plan, remote=remote)


def check_download(plan: RrdSourcePlan) -> None:
    """A remote recording's values, once `run` has it at `plan.path`: every chunk of the component decodes."""
    _check_values(_open_store(plan.path, shown_file(plan), plan.where), plan, shown_file(plan), plan.where)


def _check_values(store: LazyStore, plan: RrdSourcePlan, shown: str, where: Where) -> None:
    read_all(store.stream().filter(content=plan.entity, is_static=False, components=plan.component), shown, where)


def _compiled(store: LazyStore, path: Path, file_name: str, name: str, spec: dict[str, Any], document: Document) -> RrdSourcePlan:
    """The plan from the recording's manifest and its names (static, or the first row's): no value is read."""
    here = ("sources", name)
    schema = store.schema()
    entity = rooted(spec["entity"])
    component = spec.get("component", DEFAULT_COMPONENT)
    if entity not in schema.entity_paths():
        numeric = sorted({c.entity_path for c in schema.component_columns() if c.component == DEFAULT_COMPONENT})
        raise UserError(
            f"entity '{entity}' not in {file_name}; entities with {DEFAULT_COMPONENT}: {', '.join(numeric) or 'none'}",
            document.where(*here, "entity"),
        )
    column = schema.column_for(entity, component)
    if column is None:
        present = sorted(c.component for c in schema.columns_for(entity_path=entity))
        raise UserError(
            f"entity '{entity}' has no component '{component}'; it has: {', '.join(present)}", document.where(*here, "component")
        )
    if column.is_static:
        raise UserError(f"'{entity}' {component} is static: it has no rows over time", document.where(*here, "component"))
    column_type = schema.to_arrow().field(column.name).type
    layout = layout_of(column_type)
    if layout is None:
        raise UserError(
            f"'{entity}' {component} is {column_type}: neither numbers per row (like Scalars) nor one list of numbers per row",
            document.where(*here, "component"),
        )
    names_column = schema.column_for(entity, NAMES_COMPONENT) if component != NAMES_COMPONENT else None
    named_rows = names_column is not None and not names_column.is_static
    if named_rows and layout != "scalars":
        raise UserError(
            f"'{entity}' has per-row {NAMES_COMPONENT} but {component} holds one list per row; per-row names need one value per instance",
            document.where(*here, "component"),
        )
    given = tuple(spec["names"]) if "names" in spec else None
    recorded = _static_names(store, entity) if names_column is not None and names_column.is_static else ()
    if given is not None and recorded and given != recorded:
        raise UserError(
            f"names differ from the {NAMES_COMPONENT} recorded on '{entity}' ({', '.join(recorded)}); remove names: or make them equal",
            document.where(*here, "names"),
        )
    names = given or recorded or (_first_row_names(store, entity) if named_rows else ())
    if not names:
        raise UserError(f"'{entity}' carries no {NAMES_COMPONENT}; give the names with names: [...]", document.where(*here))
    if len(set(names)) != len(names):
        raise UserError(f"the names recorded on '{entity}' name a value twice: {', '.join(names)}", document.where(*here))
    return with_duplicates(RrdSourcePlan(name, path, entity, component, named_rows, names, document.where(*here)), spec)


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the entity's names (its SeriesLines:names), as `validate` reads them; PART names the entity."""
    given = file_input(path)
    if part is None:
        raise UserError(f"name the entity holding the values with rrd:FILE#ENTITY, e.g. rrd:{given.file.name}#/observation.state")
    plan = compile_source(name, {"rrd": str(given.file), "entity": part}, document, given.file.parent)
    fields = (EntryField("entity", rooted(part)),)
    return SourceDescription("rrd", fields, plan.names, None, given.segment, pattern=given.pattern)


def _one_instance_per_row(plan: RrdSourcePlan, chunk: Chunk) -> list[Chunk]:
    """Repack the rows that hold values: a vector per row, or {name, position} per row when the names are per row."""
    from rerun.chunk import Chunk

    batch = chunk.to_record_batch()
    index = batch.schema.get_field_index(plan.component)
    if index < 0:
        return []
    holds_values = batch.column(index).is_valid()
    if not pc.all(holds_values).as_py():  # rows of other components in the same chunk
        batch = batch.filter(holds_values)
    if not batch.num_rows:
        return []
    values = batch.column(index)
    if plan.named_rows:
        names_index = batch.schema.get_field_index(NAMES_COMPONENT)
        names = batch.column(names_index) if names_index >= 0 else pa.nulls(batch.num_rows, pa.list_(pa.string()))
        if names.null_count:
            raise UserError(
                f"'{plan.entity}' has {names.null_count} rows of {plan.component} without {NAMES_COMPONENT} (in one batch); "
                "rows with per-row names must all carry them",
                plan.where,
            )
        column, component = named_rows_column(names, values), NAMED_COMPONENT
        batch = batch.set_column(index, component_field(component, column.type), column).remove_column(names_index)
    elif layout_of(values.type) == "scalars":
        column = per_row(values)
        batch = batch.set_column(index, component_field(VECTOR_COMPONENT, column.type), column)
    else:
        counts = values.value_lengths().to_numpy(zero_copy_only=False)
        if np.any(counts != 1):
            raise UserError(
                f"'{plan.entity}' {plan.component} has rows of {int(counts[counts != 1][0])} lists; one list of values per row is needed",
                plan.where,
            )
        batch = batch.set_column(index, component_field(VECTOR_COMPONENT, values.type), values)
    return Chunk.from_record_batch(batch)


def open_stream(plan: RrdSourcePlan) -> SourceStream:
    from rerun.chunk import RrdReader

    components = [plan.component, NAMES_COMPONENT] if plan.named_rows else plan.component
    stream = (
        RrdReader(plan.path)
        .store()
        .stream()
        .filter(content=plan.entity, is_static=False, components=components)
        .flat_map(partial(_one_instance_per_row, plan))
    )
    stream = in_time_order(stream, None, plan, shown_file(plan))
    component = NAMED_COMPONENT if plan.named_rows else VECTOR_COMPONENT
    return SourceStream(stream, plan.entity, component, len(plan.names), named=plan.named_rows)

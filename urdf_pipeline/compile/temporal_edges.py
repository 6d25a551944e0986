"""Temporal edges (a pose read from a source row by row: a mobile base, a floating pelvis) compiled: their values
found by name, their entity chosen; `execute/temporal_stream.py` places them row by row."""

from __future__ import annotations

import re

from ..config import EdgeSpec
from ..errors import closest, listing
from ..plan import TemporalEdgePlan
from .context import UNKNOWN_INDEX, CompileContext, SourceNames

TEMPORAL_ENTITY = "/calibration/temporal"


def describe_temporal_edge(edge: TemporalEdgePlan) -> str:
    topic = f", {edge.tf_topic} of its bag" if edge.tf_topic is not None else ""
    return f"temporal edge {edge.parent} -> {edge.child} ({edge.label}, source '{edge.source}'{topic})"


class TemporalEntities:
    """What the temporal edges of one config share, so that each edge costs the same however many there are: the
    entity paths taken (and the next free suffix of each), and each source's value names by position."""

    def __init__(self) -> None:
        self.taken: set[str] = set()
        self.next_suffix: dict[str, int] = {}
        self.positions: dict[str, dict[str, int]] = {}

    def entity_for(self, child: str) -> str:
        """`/calibration/temporal/CHILD`, with characters an entity path part cannot hold replaced, unique per edge."""
        part = re.sub(r"[^A-Za-z0-9_.-]", "_", child) or "_"
        entity = f"{TEMPORAL_ENTITY}/{part}"
        suffix = self.next_suffix.get(part, 2)
        while entity in self.taken:
            entity = f"{TEMPORAL_ENTITY}/{part}_{suffix}"
            suffix += 1
        self.next_suffix[part] = suffix
        self.taken.add(entity)
        return entity

    def position(self, source: str, names: tuple[str, ...], value: str) -> int | None:
        """Where `value` is among the names of `source` (the first, as tuple.index), None when it is not there."""
        positions = self.positions.get(source)
        if positions is None:
            positions = self.positions[source] = {}
            for index, name in enumerate(names):
                positions.setdefault(name, index)
        return positions.get(value)


def compile_temporal_edge(ctx: CompileContext, edge: EdgeSpec, sources: SourceNames, entities: TemporalEntities) -> TemporalEdgePlan | None:
    """Check the source and every value name now (metadata only); values are checked in the data pass. `entities`
    holds the entity paths earlier temporal edges took; this edge's is added. A source whose names only its data
    holds (`validate --no-data`) leaves the value names unchecked and their positions UNKNOWN_INDEX."""
    problems, defined = ctx.problems, ctx.source_names
    spec = edge.spec
    name = spec["source"]
    if name not in sources:
        if name not in defined:
            problems.add(f"no source named '{name}'; sources are: {', '.join(sorted(defined)) or 'none'}", edge.where("source"))
        return None  # else the source itself is broken and already reported
    names = sources[name]
    missing = False
    for key in ("translation", "quaternion_xyzw"):
        for index, value in enumerate(spec[key]):
            if names is not None and entities.position(name, names, value) is None:
                close = closest(value, names)
                hint = f" (did you mean '{close}'?)" if close is not None else f"; it has: {listing(names)}"
                problems.add(f"source '{name}' has no value named '{value}'{hint}", edge.where(key, index))
                missing = True
    if missing:
        return None
    translation = tuple(spec["translation"])
    quaternion = tuple(spec["quaternion_xyzw"])

    def at(value: str) -> int:
        position = entities.position(name, names, value) if names is not None else None
        return position if position is not None else UNKNOWN_INDEX

    return TemporalEdgePlan(
        parent=spec["parent"],
        child=spec["child"],
        source=name,
        translation_names=translation,
        quaternion_names=quaternion,
        translation_indices=tuple(at(v) for v in translation),  # type: ignore[arg-type]
        quaternion_indices=tuple(at(v) for v in quaternion),  # type: ignore[arg-type]
        entity=entities.entity_for(spec["child"]),
        label=edge.label,
        where=edge.where(),
    )

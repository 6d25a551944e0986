"""Joint-value sources. A kind is one module that follows `base.SourceKind`, registered in KINDS under the config key
that selects it (the one list of kinds: `init`'s `KIND:PATH` forms and file suffixes come from it too). Kinds import
`base` and their siblings, never this package's __init__.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..package import lazy_surface
from ..plan import SourcePlan
from . import csv, hdf5, lerobot, mcap, parquet, rrd

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it), with the names defined below
    from .bag_contents import BagTransform, robot_description, static_transforms, tf_messages, tf_pairs
    from .base import GLOB, EntryField, SourceDescription, SourceKind, refuse_control_characters, resolve_input
    from .callbacks import CallbackErrors
    from .joint_state_cdr import JOINT_STATE, MAX_NAMES, MAX_SCHEMA_BYTES, JointStateUnreadable, definition_differs, read_joint_state
    from .joint_values import ChannelStats, JointValueMapper, RobotStats, raw_matrix, wrapped
    from .lerobot import local_dataset
    from .mcap import MCAP_TIMELINES, checked_first_names
    from .mcap_chunks import HEAD, MAGIC, InflationBudget, McapRefused, chunk_records, parsed_chunk, refusal, short_reason
    from .ordering import NeedsSorting, sorted_in_memory, with_sorting_retry
    from .stream import SourceStream
    from .time_range import INT64_MAX

KINDS: dict[str, SourceKind] = {"lerobot": lerobot, "parquet": parquet, "mcap": mcap, "hdf5": hdf5, "rrd": rrd, "csv": csv}


def kind_of(spec: dict[str, Any]) -> str:
    return next(kind for kind in KINDS if kind in spec)


def module_for(plan: SourcePlan) -> SourceKind:
    return next(module for module in KINDS.values() if isinstance(plan, module.PLAN_TYPE))


def kind_for_path(path: str) -> str | None:
    """The kind a path says, for `init` when `KIND:` is left out: its file suffix, else a LeRobot dataset's folder."""
    suffix = Path(path).suffix.lower()
    by_suffix = {ending: kind for kind, module in KINDS.items() for ending in module.SUFFIXES}
    if suffix in by_suffix:
        return by_suffix[suffix]
    return "lerobot" if lerobot.is_dataset(Path(path)) else None


if not TYPE_CHECKING:
    _SURFACE, __getattr__ = lazy_surface(__name__, __file__)
    __all__ = [*_SURFACE, "KINDS", "kind_for_path", "kind_of", "module_for"]

"""What a live view is given, as the (rows x source names) float64 matrix a run's mapper reads.

A push gives one sample as a sequence in the source's `names` order or a mapping name -> value; a batch, rows of
either; a stream's JointState messages name their own positions, in an order that may change between messages. A
wrong number of values, a name the source does not have, or a missing name a robot reads is refused, naming it, at
the first sample that shows it: the mapping is the config's, never guessed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import UserError, did_you_mean, listing, quoted
from ..plan import LiveSource

_CACHED_ORDERS = 64  # distinct name orders kept per source (a driver publishes one, or a few)


class ValueRows:
    """One source's pushes -> raw rows. `required`: the positions (in the source's names) the robot and its
    temporal edges read; other names may be left out of a mapping or a message and stay NaN."""

    def __init__(self, source: LiveSource, required: np.ndarray, label: str) -> None:
        self.source = source
        self.width = len(source.names)
        self.position = {name: i for i, name in enumerate(source.names)}
        self.required = required
        self.label = label  # "urdf_pipeline.live robot 'arm'", "topic '/joint_states'"
        self._orders: dict[tuple[str, ...], np.ndarray] = {}

    def many(self, values: Sequence[Any] | np.ndarray) -> np.ndarray:
        """Rows of a batch (`[values]`: one push): a (rows x width) array, or a sequence of sequences or mappings."""
        if len(values) and isinstance(values[0], Mapping):
            return self.named([tuple(v) for v in values], [np.fromiter(v.values(), np.float64, len(v)) for v in values])
        matrix = np.asarray(values, dtype=np.float64)
        if matrix.ndim != 2 or matrix.shape[1] != self.width:
            raise self._count_error(matrix.shape[-1] if matrix.ndim == 2 else matrix.size)
        return matrix

    def named(self, names: Sequence[tuple[str, ...]], values: Sequence[np.ndarray]) -> np.ndarray:
        """Rows that name their values (mappings, JointState messages): each placed by name. Rows with the same name
        tuple share one lookup; the lookups are kept per distinct order."""
        matrix = np.full((len(names), self.width), np.nan)
        for row, (order, row_values) in enumerate(zip(names, values, strict=True)):
            columns = self._orders.get(order)
            if columns is None:
                columns = self._columns(order)
            matrix[row, columns] = row_values
        return matrix

    def _columns(self, order: tuple[str, ...]) -> np.ndarray:
        strangers = [name for name in order if name not in self.position]
        if strangers:
            hint = did_you_mean(strangers[0], self.source.names)
            raise UserError(
                f"{self.label} names {listing([quoted(n) for n in strangers], limit=8)}, not among source '{self.source.name}''s names"
                f"{hint}; list every name the data carries in sources.{self.source.name}.names and map or ignore it",
                self.source.where,
            )
        columns = np.array([self.position[name] for name in order], dtype=np.intp)
        if len(np.unique(columns)) != len(columns):
            twice = sorted({name for name in order if order.count(name) > 1})
            raise UserError(f"{self.label} names {listing([quoted(n) for n in twice])} twice in one sample", self.source.where)
        missing = np.setdiff1d(self.required, columns)
        if missing.size:
            lacking = [quoted(self.source.names[i]) for i in missing]
            raise UserError(
                f"{self.label} gives no value for {listing(lacking, limit=8)}, which the config maps; every sample must name them",
                self.source.where,
            )
        if len(self._orders) >= _CACHED_ORDERS:
            self._orders.pop(next(iter(self._orders)))
        self._orders[order] = columns
        return columns

    def _count_error(self, found: int) -> UserError:
        return UserError(
            f"{self.label} was given {found} values; source '{self.source.name}' has {self.width} names "
            f"({listing(list(self.source.names), limit=6)}): give one value per name, in that order, or a mapping name -> value",
            self.source.where,
        )

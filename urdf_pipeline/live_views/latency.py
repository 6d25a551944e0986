"""Latency from a sample reaching this process to it being sent to the viewer, in bounded memory at any length: counts
in log-spaced bins (1 µs .. 100 s, 40 per decade: a quantile within 3 %), never a list of every sample."""

from __future__ import annotations

import numpy as np

_LOW_NS, _DECADES, _PER_DECADE = 1_000, 8, 40
_EDGES = _LOW_NS * 10.0 ** (np.arange(_DECADES * _PER_DECADE + 1) / _PER_DECADE)


class Latencies:
    def __init__(self) -> None:
        self.counts = np.zeros(len(_EDGES) + 1, dtype=np.int64)  # below the first edge, the bins, beyond the last

    def add(self, nanoseconds: np.ndarray) -> None:
        self.counts += np.bincount(np.searchsorted(_EDGES, nanoseconds, side="right"), minlength=len(self.counts))

    @property
    def total(self) -> int:
        return int(self.counts.sum())

    def quantile(self, q: float) -> float:
        """Seconds: the geometric middle of the bin holding the q-th sample (0 when none was measured)."""
        if not self.total:
            return 0.0
        index = int(np.searchsorted(np.cumsum(self.counts), q * self.total, side="left"))
        low = _EDGES[max(index - 1, 0)]
        high = _EDGES[min(index, len(_EDGES) - 1)]
        return float(np.sqrt(low * high)) / 1e9

    def text(self) -> str:
        if not self.total:
            return "no samples"
        return f"median {self.quantile(0.5) * 1e3:.2f} ms, 99th percentile {self.quantile(0.99) * 1e3:.2f} ms"

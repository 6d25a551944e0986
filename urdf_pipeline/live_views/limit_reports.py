"""What a live view reports of the values it is given: limits, NaN, dropped rows, as a run reports them after its
pass, but over windows of a few seconds, at most one report per window. A stream cannot be refused: values beyond the
limits are clamped or shown as given (`joints.limits.on_violation`: clamp clamps; error and ignore show them, error
as an error-worded warning naming the likely cause), and a sample with NaN values is left out unless `joints.nan`
says how to fill it.
"""

from __future__ import annotations

import time

from ..errors import Problems, Where, warn
from ..execute import TemporalEdgeStats, TemporalEdgeValues, check_joint_statistics, check_temporal_edges
from ..plan import LiveSource
from ..sources import ChannelStats, JointValueMapper, RobotStats

REPORT_SECONDS = 5.0


class LimitReports:
    """The window's statistics of one live view's mapper and temporal edges, reported when something is wrong and
    the last report is `every` seconds old (the first at once), then started afresh."""

    def __init__(
        self, mapper: JointValueMapper, temporal: list[TemporalEdgeValues], source: LiveSource, every: float = REPORT_SECONDS
    ) -> None:
        self.mapper, self.temporal, self.source, self.every = mapper, temporal, source, every
        self.last = -float("inf")
        self.before = 0  # samples of the windows already reported: row numbers in messages count from the view's start

    def due(self) -> bool:
        return time.monotonic() - self.last >= self.every and self._anything()

    def report(self, final: bool = False) -> None:
        """The window's warnings (`final`: whatever is left when the view closes), then a fresh window."""
        if not (self._anything() and (final or self.due())):
            return
        for channel in self.mapper.stats.channels:
            if channel.first_nonfinite_row >= 0:
                channel.first_nonfinite_row += self.before
        problems = Problems()
        lines: list[tuple[str, Where | None]] = [(text, None) for text in check_joint_statistics(self.mapper, problems)]
        check_temporal_edges([v for v in self.temporal if v.stats.rows], problems)
        lines += [(error.message, error.where) for error in problems.errors]
        window = "since the view started" if self.last == -float("inf") else f"in the last {time.monotonic() - self.last:.0f} s"
        for text, where in lines:
            warn(f"live: {text} ({window}; a live view shows the samples it can, it cannot refuse them)", where)
        self.last = time.monotonic()
        self.before += self.mapper.stats.rows
        self.mapper.stats = RobotStats(channels=[ChannelStats() for _ in self.mapper.robot.channels])
        for values in self.temporal:
            values.stats = TemporalEdgeStats()

    def _anything(self) -> bool:
        stats = self.mapper.stats
        if stats.dropped_rows or stats.filled_rows:
            return True
        if any(c.clamped_rows or c.beyond_rows or c.nonfinite_rows for c in stats.channels):
            return True
        return any(v.stats.nonfinite_rows or v.stats.zero_quaternion_rows for v in self.temporal)

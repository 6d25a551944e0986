"""`urdf-pipeline live CONFIG --from URL`: a robot's stream into a viewer and/or a file, with the config's checks
(docs/live.md says what it does at the first message, at its end, and on Ctrl-C and SIGTERM).

The config is checked before anything is subscribed (`FROM_STREAM`, as `validate --live`), and the plan compiled once
every source's names are known (`names:`, or the first message on its topic). A signal ends the view as the end of
the stream does, then ends the command as it ends any other (`process.deferred_signals`: exit 130, 143).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..compile import FROM_STREAM, Compiled, check_config
from ..errors import UserError, UserErrors, Where, shown
from ..execute import provenance_stream, write_file_atomically
from ..logs import say
from ..plan import LivePlan
from ..process import Stopped, deferred_signals, signal_name, stop_signal
from ..sources import checked_first_names
from .joint_state import Feed, JointStateSample, same_topic
from .live_view import LiveView
from .prefetch import MAX_QUEUED_BYTES, Prefetched, WaitingSamples

if TYPE_CHECKING:
    from rerun import RecordingStream

FROM_OPTION = Where(Path("--from"), 0)
SAVE_OPTION = Where(Path("--save"), 0)
WAIT_NOTE_SECONDS = 5.0  # "waiting for the first message on ..." repeated this often
MAX_EARLY_SAMPLES = 10_000  # kept while the first messages of other topics are awaited (and MAX_QUEUED_BYTES)


@dataclass(frozen=True)
class LiveOptions:
    config: Path
    source: str  # --from: ws://HOST:PORT, or an MCAP file being written
    viewer_url: str | None  # --connect / --spawn, settled by the command line
    save: Path | None
    reconnects: int = 10


_LOW_NS, _DECADES, _PER_DECADE = 1_000, 8, 40
_EDGES = _LOW_NS * 10.0 ** (np.arange(_DECADES * _PER_DECADE + 1) / _PER_DECADE)


class Latencies:
    """Latency from a sample reaching this process to it being sent to the viewer, in bounded memory at any length:
    counts in log-spaced bins (1 µs .. 100 s, 40 per decade: a quantile within 3 %), never a list of every sample."""

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


@dataclass
class LiveSummary:
    """What `live` says when it ends."""

    received: int = 0
    sent: int = 0
    seconds: float = 0.0
    ended: str = "the stream ended"
    latency: Latencies = field(default_factory=Latencies)
    saved: Path | None = None
    dropped: int = 0  # samples dropped because the views fell behind (said when it happens)

    def line(self) -> str:
        saved = f"; saved {self.saved}" if self.saved else ""
        dropped = f", {self.dropped} dropped behind" if self.dropped else ""
        return (
            f"live: {self.received} samples in {self.seconds:.1f} s, {self.sent} sent ({self.ended}{dropped}); "
            f"from arrival to sent: {self.latency.text()}{saved}"
        )


def open_feed(source: str, topics: Mapping[str, Where | None], reconnects: int) -> Feed:
    """`--from`: a Foxglove WebSocket server (ws://, wss://) or a path to an MCAP file being written."""
    if source.startswith(("ws://", "wss://")):
        try:
            import websockets  # noqa: F401 - the library the client needs, said before anything else
        except ImportError:
            raise UserError("live --from ws:// needs the websockets library: pip install 'urdf-pipeline[live]'", FROM_OPTION) from None
        from .foxglove_feed import FoxgloveFeed

        return FoxgloveFeed(source, topics, reconnects=reconnects)
    if "://" in source:
        raise UserError(
            f"{shown(source)}: live --from takes ws://HOST:PORT (a Foxglove WebSocket server, such as foxglove_bridge) or the path of "
            "an MCAP file being written",
            FROM_OPTION,
        )
    from .mcap_follow import McapFollowFeed

    return McapFollowFeed(Path(source), topics, FROM_OPTION)


def live_command(options: LiveOptions) -> LiveSummary:
    """Check, subscribe, show; the summary of what was seen. A problem found once samples were sent keeps them in
    `--save` (a complete recording of what came before it) and is raised after, saying so."""
    check = check_config(options.config, FROM_STREAM)
    if check.errors:
        raise UserErrors(list(check.errors))
    topics = {spec.topic: spec.where for spec in check.sources if spec.topic is not None}
    summary = LiveSummary()
    feed = open_feed(options.source, topics, options.reconnects)
    say(f"live: {options.config} from {feed.description}, topics {', '.join(shown(t) for t in topics)}")
    try:
        with deferred_signals() as stop:  # the handlers only record the signal: the session sees it between batches
            session = _Session(options, check, summary, stop)
            try:
                if options.save is None:
                    session.run(feed, None)
                else:
                    write_file_atomically(options.save, lambda partial: session.save(feed, partial), "recording", SAVE_OPTION)
                    summary.saved = options.save
            except _NothingSaved:
                pass
            if stop:
                summary.ended = f"stopped by {signal_name(stop[0])}"
                say(summary.line())  # said here: the signal goes on to the command line as the block ends
    except KeyboardInterrupt as interrupt:  # the signal, given back as the block ended: this command said its line
        raise Stopped(stop_signal(interrupt), said=True) from None
    if session.late_error is not None:
        error = session.late_error
        kept = f"; the {summary.sent} samples before it are saved in {options.save}" if options.save else ""
        raise UserError(f"{error.message}{kept}", error.where)
    return summary


class _NothingSaved(Exception):
    """No sample reached the views: `--save` writes no file (raised inside the atomic write, which removes its
    partial file)."""


class _Session:
    """One subscription's views: made once every source's names are known, fed each poll's samples."""

    def __init__(self, options: LiveOptions, check: Compiled[LivePlan], summary: LiveSummary, stop: list[int]) -> None:
        self.options, self.specs, self.summary, self.check = options, check.sources, summary, check
        self.stop = stop  # the signals received (deferred_signals): the session ends at the next batch
        self.stream_names: dict[str, tuple[str, ...]] = {}
        self.early = WaitingSamples(MAX_EARLY_SAMPLES, MAX_QUEUED_BYTES)
        self.views: dict[str, list[LiveView]] = {}  # topic as the config writes it -> views of robots its source drives
        self.stamps: dict[str, str] = {}  # topic -> header | log_time | publish_time
        self.recording: RecordingStream | None = None
        self.sent_any = False
        self.early_dropped = 0  # samples dropped while waiting for every topic's names
        self.late_error: UserError | None = None

    def run(self, feed: Feed, partial: Path | None) -> None:
        """The views first when the config names every source's values; else at the first messages. The feed is read
        ahead on a thread (prefetch.py), so the views' own pauses lose nothing."""
        started = time.monotonic()
        noted = started
        ahead = Prefetched(feed)
        try:
            if self.check.plan is not None:  # every source's names from `names:`: the check's plan
                self._make_views(self.check.plan, partial)
            for batch in ahead.batches():
                if self.stop:
                    break  # a batch that came with the signal is left out: --save holds every sample sent
                self.summary.received += len(batch)
                if self.recording is None:
                    batch = self._await_names(batch, partial)
                    if self.recording is None:
                        noted = self._note_waiting(noted)
                        continue
                self._show(batch)
        except UserError as error:
            if not self.sent_any:
                raise
            self.late_error = error
        finally:
            self.summary.seconds = time.monotonic() - started
            self.summary.dropped = ahead.dropped + self.early_dropped
            ahead.close()
            self._finish()

    def save(self, feed: Feed, partial: Path) -> None:
        """`run` into the partial file of `--save`; _NothingSaved when no sample was sent (the partial is removed)."""
        self.run(feed, partial)
        if not self.sent_any:
            raise _NothingSaved

    def _await_names(self, batch: list[JointStateSample], partial: Path | None) -> list[JointStateSample]:
        """Samples before every source's names are known are kept (bounded); then the plan and the views are made."""
        for sample in batch:
            for spec in self.specs:
                if spec.topic is not None and same_topic(spec.topic, sample.topic) and spec.name not in self.stream_names:
                    self.stream_names[spec.name] = spec.names or checked_first_names(
                        sample.names, sample.topic, self.options.source, spec.where
                    )
        self.early_dropped += self.early.append(batch) if batch else 0  # said by _note_waiting, counted in the last line
        if len(self.stream_names) < len([s for s in self.specs if s.topic is not None]):
            return []
        self._make_views(check_config(self.options.config, replace(FROM_STREAM, stream=self.stream_names)).checked(), partial)
        return self.early.take_all()

    def _make_views(self, plan: LivePlan, partial: Path | None) -> None:
        _require_robots(plan)
        self.recording = live_recording(plan.application_id, partial, self.options.viewer_url)
        self.recording.send_chunks(provenance_stream(plan, "all", {"live_from": self.options.source}))
        for source in plan.sources:
            assert source.topic is not None
            self.stamps[source.topic] = source.stamp
            robots = plan.robots_for(source.name)
            self.views[source.topic] = [
                LiveView(plan, robot, self.recording, scene=not self.views and not i) for i, robot in enumerate(robots)
            ]

    def _note_waiting(self, noted: float) -> float:
        if time.monotonic() - noted < WAIT_NOTE_SECONDS:
            return noted
        waiting = [shown(s.topic) for s in self.specs if s.topic is not None and s.name not in self.stream_names]
        dropped = f" (the {self.early_dropped} oldest samples of the others dropped meanwhile)" if self.early_dropped else ""
        say(f"live: waiting for the first message on {', '.join(waiting)}{dropped}")
        return time.monotonic()

    def _show(self, batch: list[JointStateSample]) -> None:
        for topic, views in self.views.items():
            samples = [s for s in batch if same_topic(topic, s.topic)]
            if not samples:
                continue
            times = _times(samples, self.stamps[topic], views[0])
            for view in views:
                view.push_named([s.names for s in samples], [s.positions for s in samples], times)
            self.sent_any = True
            self.summary.sent += len(samples)
            received = np.fromiter((s.received_ns for s in samples), np.int64, len(samples))
            self.summary.latency.add(time.monotonic_ns() - received)

    def _finish(self) -> None:
        problems: list[BaseException] = []
        for view in (v for views in self.views.values() for v in views):
            _closing(view.close, problems)
        if self.recording is not None:
            _closing(self.recording.flush, problems)
            _closing(self.recording.disconnect, problems)
        if problems:
            raise problems[0]


def _closing(step: Callable[[], Any], problems: list[BaseException]) -> None:
    try:
        step()
    except BaseException as exc:  # every view and the recording are closed; the first failure is raised
        problems.append(exc)


def _require_robots(plan: LivePlan) -> None:
    for source in plan.sources:
        if not plan.robots_for(source.name):
            raise UserError(
                f"source '{source.name}' drives no robot, only temporal edges; live shows robots driven by a topic "
                "(a temporal edge read from a stream alone is not supported yet)",
                source.where,
            )


def _times(samples: list[JointStateSample], stamp: str, view: LiveView) -> np.ndarray:
    """Each sample's time on the source's timeline, as a run of the same bag places it; a zero header stamp is
    refused as a run refuses it."""
    if stamp == "log_time":
        return np.fromiter((s.log_time_ns for s in samples), np.int64, len(samples))
    if stamp == "publish_time":
        return np.fromiter((s.publish_time_ns for s in samples), np.int64, len(samples))
    times = np.fromiter((s.header_ns for s in samples), np.int64, len(samples))
    if not times.all():
        raise UserError(
            f"messages on '{shown(samples[0].topic)}' have a zero header stamp, so they would all sit at time 0; set "
            f"sources.{view.source.name}.timeline: log_time to use the time the messages were sent",
            view.source.where,
        )
    return times


def live_recording(application_id: str, save: str | os.PathLike[str] | Path | None, *viewers: str | None) -> RecordingStream:
    """A new recording (when the caller gives none) whose sinks are the viewers at `viewers` (None: not one, their URLs
    settled by the caller: `process.spawn_viewer`, `process.require_viewer`) and the file `save`, as asked."""
    import rerun as rr

    sinks: list[Any] = [rr.GrpcSink(url) for url in viewers if url is not None]
    if save is not None:
        sinks.append(rr.FileSink(str(save)))
    recording = rr.RecordingStream(application_id)
    recording.set_sinks(*sinks)
    return recording

"""`live --from ws://HOST:PORT`: JointState samples from a robot's Foxglove WebSocket server (foxglove_bridge on ROS 2,
or any Foxglove SDK server). The config's topics are subscribed when advertised (a driver started after us too), the
connection is kept (a lost one reconnected with backoff and its topics subscribed again by name: a restarted server
gives new channel ids), and nothing waits without a bound.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator, Mapping
from typing import Any, NamedTuple

from ..errors import UserError, Where, quoted, shown
from ..logs import detail, say
from .foxglove_protocol import Advertised, ProtocolError, advertised, message_data, server_message, subscribe, unadvertised
from .foxglove_socket import BINARY, CONNECT_SECONDS, TEXT, Connection, Lost, check_url
from .joint_state import JOINT_STATE, POLL_SECONDS, JointStateDecoder, JointStateSample, NameOrders, same_topic

MAX_BATCH = 1000  # frames read into one batch: the caller gets to stop or flush between batches, however fast data comes
MAX_BATCH_BYTES = 1024 * 1024  # and their bytes (a batch's samples are a small multiple of them: joint_state.names_bytes)
FIRST_DELAY, MAX_DELAY = 0.25, 2.0  # seconds before a reconnect: doubling from the first to the most
NOTE_AFTER_SECONDS = 2.0  # connected this long with no wanted topic advertised: say so, once per connection
MAX_RESUBSCRIBES, RESUBSCRIBE_SECONDS = 8, 0.1  # per connection, each later than the last: _Session._subscribe_again
MAX_CHANNELS = 64  # channels of the wanted topics subscribed per connection (a server's endless advertisements refused)
MAX_STATUS_LINES = 10  # the server's warnings and errors said per connection (a server may repeat one forever)
_LISTED_TOPICS = 8
_UNKNOWN_CHANNEL = re.compile(r"Unknown channel ID: (\d+)")  # foxglove-sdk's status for a channel it does not know


class _Subscription(NamedTuple):
    topic: str  # the wanted topic, as the config writes it
    decoder: JointStateDecoder


class _Session:
    """One connection's state: the channels subscribed, and the samples its frames give."""

    def __init__(self, connection: Connection, wanted: Mapping[str, Where | None], orders: Mapping[str, NameOrders]) -> None:
        self.connection, self.url = connection, shown(connection.url)
        self._wanted, self._orders = wanted, orders
        self.received = False  # a sample came: the connection works (the reconnect count starts again)
        self._subscriptions: dict[int, _Subscription] = {}  # our subscription id -> its topic and decoder
        self._by_channel: dict[int, int] = {}  # the server's channel id -> our subscription id
        self._next_subscription = 0
        self._statuses = 0  # status lines said
        self._resubscribed = 0  # subscriptions sent again (_subscribe_again)
        self._again: dict[int, float] = {}  # channel id -> when to subscribe it again
        self._other_topics: dict[str, None] = {}  # advertised, not wanted: named in the note
        self._opened, self._noted = time.monotonic(), False
        self._failure: Lost | UserError | None = None  # what ended a batch that had samples: raised by the next

    def handshake(self) -> None:
        """The server's first message must be its serverInfo, within CONNECT_SECONDS."""
        deadline = time.monotonic() + CONNECT_SECONDS
        while (left := deadline - time.monotonic()) > 0:
            frame = self.connection.receive(min(left, POLL_SECONDS))
            if frame is None:
                continue
            if frame[0] == TEXT and self._message(frame[1])["op"] == "serverInfo":
                return
            raise UserError(f"{self.url} is not a Foxglove WebSocket server: its first message is no Foxglove serverInfo")
        raise UserError(
            f"{self.url} sent no Foxglove serverInfo within {CONNECT_SECONDS:g} s of the WebSocket handshake; is it a Foxglove WebSocket server?"
        )

    def batch(self) -> list[JointStateSample]:
        """The samples of the frames that came within POLL_SECONDS, and of all those already here after them."""
        if self._failure is not None:
            raise self._failure
        samples: list[JointStateSample] = []
        try:
            frame, taken, size = self.connection.receive(POLL_SECONDS), 0, 0
            while frame is not None:
                self._take(*frame, samples)
                taken, size = taken + 1, size + len(frame[1])
                if taken == MAX_BATCH or size >= MAX_BATCH_BYTES or not self.connection.pending():
                    break
                frame = self.connection.receive(POLL_SECONDS)
        except (Lost, UserError) as failure:  # the samples read before it are given first
            if not samples:
                raise
            self._failure = failure
            return samples
        self.connection.keep_alive()
        self._subscribe_due()
        self._note_missing()
        return samples

    def _take(self, opcode: int, data: bytes, received_ns: int, samples: list[JointStateSample]) -> None:
        try:
            if opcode == TEXT:
                self._control(server_message(data))
            elif opcode == BINARY and (parsed := message_data(data)) is not None:
                if (subscription := self._subscriptions.get(parsed[0])) is not None:
                    samples.append(self._sample(subscription, parsed[1], parsed[2], received_ns))
        except ProtocolError as exc:
            raise self._broken(exc) from None

    def _sample(self, subscription: _Subscription, timestamp_ns: int, payload: memoryview, received_ns: int) -> JointStateSample:
        try:
            header_ns, names, positions = subscription.decoder(payload)
        except UserError as error:
            raise UserError(f"{error.message} (from {self.url})", error.where) from None
        self.received = True
        return JointStateSample(subscription.topic, names, positions, header_ns, timestamp_ns, timestamp_ns, received_ns)

    def _message(self, data: bytes) -> dict[str, Any]:
        try:
            return server_message(data)
        except ProtocolError as exc:
            raise self._broken(exc) from None

    def _broken(self, exc: ProtocolError) -> UserError:
        return UserError(f"{self.url} does not speak the Foxglove WebSocket protocol: it sent {shown(exc)}")

    def _control(self, message: dict[str, Any]) -> None:
        if message["op"] == "advertise":
            self._advertise(advertised(message))
        elif message["op"] == "unadvertise":
            for channel in unadvertised(message):
                self._subscriptions.pop(self._by_channel.pop(channel, -1), None)
        elif message["op"] == "status":
            self._status(message)

    def _status(self, message: dict[str, Any]) -> None:
        """The server's warnings and errors (a subscription it refused: why no data comes), the first few of each
        connection; its infos are left out."""
        text = message.get("message")
        unknown = _UNKNOWN_CHANNEL.fullmatch(text) if isinstance(text, str) else None
        if unknown is not None and self._subscribe_again(int(unknown[1])):
            return
        if message.get("level") in (1, 2) and self._statuses < MAX_STATUS_LINES:
            self._statuses += 1
            level = "error" if message["level"] == 2 else "warning"
            say(f"live: {self.url} says ({level}): {shown(message.get('message'))}")

    def _subscribe_again(self, channel: int) -> bool:
        """foxglove-sdk (0.30) sends a new channel's advertise before it records the channel, and answers a
        subscription that comes in between with "Unknown channel ID" (its connected_client.rs): a channel we
        subscribed is subscribed again a moment later (by `batch`), a few times per connection at most."""
        if channel not in self._by_channel or self._resubscribed >= MAX_RESUBSCRIBES:
            return False
        self._resubscribed += 1
        self._again[channel] = time.monotonic() + RESUBSCRIBE_SECONDS * self._resubscribed  # a starved server: later
        detail(f"live: {self.url} did not know channel {channel} yet; subscribing again")
        return True

    def _subscribe_due(self) -> None:
        """The subscriptions `_subscribe_again` put off whose time has come (of channels still advertised)."""
        now = time.monotonic()
        due = [channel for channel, at in self._again.items() if at <= now]
        for channel in due:
            del self._again[channel]
        again = [(self._by_channel[channel], channel) for channel in due if channel in self._by_channel]
        if again:
            self.connection.send(subscribe(again))

    def _advertise(self, channels: list[Advertised]) -> None:
        """Subscribe each new channel of a wanted topic, its decoder made (and its schema checked) first."""
        new = []
        for channel in channels:
            topic = next((wanted for wanted in self._wanted if same_topic(wanted, channel.topic)), None)
            if topic is None:
                if len(self._other_topics) <= _LISTED_TOPICS:  # the note names a few: a server's endless topics are not kept
                    self._other_topics.setdefault(channel.topic)
            elif channel.id not in self._by_channel:
                if len(self._subscriptions) >= MAX_CHANNELS:
                    raise UserError(
                        f"{self.url} advertised more than {MAX_CHANNELS} channels of {' or '.join(quoted(t) for t in self._wanted)}; "
                        "a Foxglove server advertises one per topic and message type"
                    )
                subscription = self._next_subscription = self._next_subscription + 1
                self._subscriptions[subscription] = _Subscription(topic, self._decoder(topic, channel))
                self._by_channel[channel.id] = subscription
                new.append((subscription, channel.id))
        if new:
            self.connection.send(subscribe(new))

    def _decoder(self, topic: str, channel: Advertised) -> JointStateDecoder:
        where = self._wanted[topic]
        try:  # the decoder's `where` is typed Where; None (a topic not from a config) is a UserError's "no location"
            return JointStateDecoder(
                topic, channel.schema_name, channel.schema_encoding, channel.schema, channel.encoding, where, self._orders[topic]
            )
        except UserError as error:
            raise UserError(
                f"{error.message}, at {self.url}; the config's source must name a topic of {JOINT_STATE} messages", where
            ) from None

    def _note_missing(self) -> None:
        if self._noted or self._subscriptions or time.monotonic() - self._opened < NOTE_AFTER_SECONDS:
            return
        self._noted = True
        others = list(self._other_topics)
        listed = ", ".join(quoted(topic) for topic in others[:_LISTED_TOPICS]) + (", …" if len(others) > _LISTED_TOPICS else "")
        wanted = " or ".join(quoted(topic) for topic in self._wanted)
        say(f"live: {self.url} has no topic {wanted} yet ({f'it has {listed}' if others else 'it advertises no topic'}); waiting for it")


class _Retries:
    """The reconnect count (attempts in a row; a connection that gave samples starts it again) and its lines."""

    def __init__(self, url: str, limit: int) -> None:
        self.url, self.limit = shown(url), limit
        self.failures, self.connected_once = 0, False

    def connected(self) -> None:
        if self.failures:
            say(f"live: {'reconnected' if self.connected_once else 'connected'} to {self.url}")
        self.connected_once = True

    def failed(self, reason: str) -> float:
        """The seconds to wait before the next attempt, said in a line; UserError once the attempts are used up."""
        self.failures += 1
        if self.failures > self.limit and self.connected_once:
            raise UserError(
                f"lost {self.url} after {_times(self.limit, 'reconnect')}: {reason}; is the robot's Foxglove server (foxglove_bridge) still running?"
            )
        if self.failures > self.limit:
            raise UserError(
                f"cannot reach {self.url} ({reason}) in {_times(self.limit + 1, 'attempt')}; is the robot's Foxglove server (foxglove_bridge) running, and is the port right?"
            )
        delay = min(FIRST_DELAY * 2 ** (self.failures - 1), MAX_DELAY)
        what = f"lost {self.url} ({reason}); reconnecting" if self.connected_once else f"cannot reach {self.url} ({reason}); trying again"
        say(f"live: {what} in {delay:g} s ({self.failures} of {self.limit})")
        return delay


def _times(count: int, what: str) -> str:
    return f"{count} {what}{'' if count == 1 else 's'}"


class FoxgloveFeed:
    """A `Feed` of the JointState messages a Foxglove WebSocket server publishes on the wanted topics.

    `topics`: the topics as the config writes them (a channel matches with or without the leading "/"), each with
    the `Where` of its config source, for the refusals. `reconnects`: attempts in a row before giving up."""

    def __init__(self, url: str, topics: Mapping[str, Where | None], reconnects: int = 10) -> None:
        if not topics:
            raise ValueError("a Foxglove feed needs a topic")
        self.description = check_url(url)
        self._wanted = dict(topics)
        self._reconnects = reconnects
        self._orders = {topic: NameOrders() for topic in topics}  # names interned per topic, across reconnects
        self._stop = threading.Event()
        self._guard = threading.Lock()  # over _connection, which close() ends from another thread
        self._connection: Connection | None = None

    def batches(self) -> Iterator[list[JointStateSample]]:
        retries = _Retries(self.description, self._reconnects)
        try:
            while not self._stop.is_set():
                try:
                    yield from self._stream(retries)
                except Lost as lost:
                    self._drop()
                    if not self._stop.is_set():
                        yield from self._pause(retries.failed(lost.reason))
        finally:
            self._drop()

    def close(self) -> None:
        """Ends `batches()` at once (a connect, a handshake or a read under way ended), from any thread."""
        self._stop.set()
        with self._guard:
            connection = self._connection
        if connection is not None:
            connection.goodbye()

    def _stream(self, retries: _Retries) -> Iterator[list[JointStateSample]]:
        session = _Session(self._connect(), self._wanted, self._orders)
        session.handshake()
        retries.connected()
        while not self._stop.is_set():
            batch = session.batch()
            if session.received:
                retries.failures = 0
            yield batch

    def _connect(self) -> Connection:
        """A connection, registered before it opens so that close() ends its connect or handshake at once."""
        connection = Connection(self.description)
        with self._guard:
            self._connection = connection
        if self._stop.is_set():  # close() came before it could end this connection
            raise Lost("closed")
        connection.open()
        return connection

    def _drop(self) -> None:
        with self._guard:
            connection, self._connection = self._connection, None
        if connection is not None:
            connection.close()

    def _pause(self, seconds: float) -> Iterator[list[JointStateSample]]:
        """Waits `seconds` (close() cuts it short), yielding an empty batch every POLL_SECONDS meanwhile."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0 and not self._stop.wait(min(left, POLL_SECONDS)):
            yield []

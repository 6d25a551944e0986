"""`live --from FILE.mcap`: follow an MCAP file that a recorder (`ros2 bag record`, a robot's logger) is still
writing, and yield the JointState messages of the config's topics as they land.

The file is polled (its size, every POLL_INTERVAL); the bytes that came are cut into complete records
(mcap_records.py: a record not all written yet waits for the next poll) and the messages of the wanted topics decoded
by a JointStateDecoder per channel. The Footer means the writer closed the file: the follow ends. A file not there
yet is waited for (`wait_seconds`); a file that shrinks, is rewritten in place, or is replaced by another at the same
path (the recorder restarted) is read again from its start, after a line saying so.
"""

from __future__ import annotations

import os
import stat
import threading
import time
from collections.abc import Generator, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from ..errors import UserError, Where, shown
from ..logs import say
from ..sources import JOINT_STATE, MAX_SCHEMA_BYTES
from .joint_state import POLL_SECONDS, JointStateDecoder, JointStateSample, same_topic
from .mcap_records import RecordSplitter

if TYPE_CHECKING:
    from mcap.records import Channel, McapRecord, Message

POLL_INTERVAL = 0.03  # seconds between looks at the file's size: a recorder's chunk lands within one
READ_BYTES = 1 << 20  # read and decoded per step, so a backlog (a long file followed late) still yields and stops often
TAIL_BYTES = 16  # the last bytes read, checked again: a file rewritten in place past where it was read shows there
DEFINITIONS_KEPT = 4096  # Schema and Channel records a followed file may define (a bag has one per type and topic)
OTHERS_SHOWN = 20  # the other topics a line names


@dataclass
class _Topic:
    """A channel of a wanted topic and its decoder (which interns the name tuples, within its bounds)."""

    topic: str  # as the config writes it
    key: tuple[str, int, str]  # the channel's topic, schema id and encoding: a repeated Channel record keeps its decoder
    decode: JointStateDecoder


class _Reading:
    """One file at the path (one inode): its handle, the bytes read from it, its schemas and channels."""

    def __init__(self, handle: IO[bytes], name: str, where: Where | None) -> None:
        self.handle = handle
        info = os.fstat(handle.fileno())
        self.identity = (info.st_dev, info.st_ino)
        self.read_to = 0
        self.tail = b""
        self.records = RecordSplitter(name, where)
        self.schemas: dict[int, tuple[str, str, str]] = {}  # id -> name, encoding, text
        self.channels: dict[int, _Topic | None] = {}  # None: a channel of another topic
        self.others: set[str] = set()  # the other topics, for the line of a file without the wanted ones
        self.messages = 0

    def read(self) -> bytes:
        data = self.handle.read(READ_BYTES) or b""
        self.read_to += len(data)
        self.tail = (self.tail + data)[-TAIL_BYTES:]
        return data

    def rewritten(self) -> str | None:
        """Why the file must be read again from its start, if it must: it shrank, or the bytes last read changed."""
        size = os.fstat(self.handle.fileno()).st_size
        if size < self.read_to:
            return "shrank"
        if size > self.read_to and self.tail and os.pread(self.handle.fileno(), len(self.tail), self.read_to - len(self.tail)) != self.tail:
            return "was rewritten"
        return None


class McapFollowFeed:
    """The JointState messages of `topics` (each with the config's place for its errors) in an MCAP file being written;
    a `Feed`. `where` is the config's MCAP source, for the file's errors."""

    def __init__(self, path: Path, topics: Mapping[str, Where | None], where: Where | None = None, wait_seconds: float = 10.0) -> None:
        self.path = Path(path)
        self.topics = dict(topics)
        self.where = where
        self.wait_seconds = wait_seconds
        self.description = f"{shown(self.path)} (followed)"
        self._closed = threading.Event()
        self._lock = threading.Lock()  # the open file is touched under it only: close() comes from any thread
        self._file: _Reading | None = None

    def close(self) -> None:
        self._closed.set()
        with self._lock:
            self._drop()

    def batches(self) -> Iterator[list[JointStateSample]]:
        try:
            if (yield from self._wait_for_file()):
                yield from self._follow()
        finally:
            with self._lock:
                self._drop()

    def _drop(self) -> None:
        if self._file is not None:
            self._file.handle.close()
            self._file = None

    def _wait_for_file(self) -> Generator[list[JointStateSample], None, bool]:
        """Open the file, waiting up to `wait_seconds` for it to appear; False when closed first."""
        last = time.monotonic()
        deadline, said = last + self.wait_seconds, False
        while not self._closed.is_set():
            with self._lock:
                if not self._closed.is_set():
                    self._file = self._open()
                if self._file is not None:
                    return True
            if not said:
                say(f"live: waiting for {shown(self.path)} to appear (up to {self.wait_seconds:g} s)")
                said = True
            if time.monotonic() >= deadline:
                raise UserError(
                    f"{shown(self.path)} did not appear within {self.wait_seconds:g} s; start the recorder first, or check the path",
                    self.where,
                )
            if time.monotonic() - last >= POLL_SECONDS:
                yield []
                last = time.monotonic()
            self._closed.wait(POLL_INTERVAL)
        return False

    def _open(self) -> _Reading | None:
        """The file at the path, None when there is none; a folder, a FIFO or an unreadable file is refused."""
        try:
            info = os.stat(self.path)
            if stat.S_ISDIR(info.st_mode):
                raise UserError(
                    f"{shown(self.path)} is a folder; name the .mcap file in it (ros2 bag record -o DIR writes DIR/DIR_0.mcap)", self.where
                )
            if not stat.S_ISREG(info.st_mode):
                raise UserError(f"{shown(self.path)} is not a regular file; name the .mcap file the recorder writes", self.where)
            handle = open(self.path, "rb", buffering=0)  # held across polls, closed by _drop
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise UserError(f"cannot read {shown(self.path)}: {shown(exc.strerror or exc)}", self.where) from None
        return _Reading(handle, str(self.path), self.where)

    def _follow(self) -> Iterator[list[JointStateSample]]:
        last = time.monotonic()
        while True:
            step = self._step()
            if step is None:
                return  # closed
            samples, more = step
            file = self._file
            if samples or file is None or file.records.footer or time.monotonic() - last >= POLL_SECONDS:
                yield samples
                last = time.monotonic()
            if file is not None and file.records.footer:
                say(f"live: {shown(self.path)} was closed by its writer after {file.messages} messages{self._unseen(file)}")
                return
            if not more:
                self._closed.wait(POLL_INTERVAL)

    def _step(self) -> tuple[list[JointStateSample], bool] | None:
        """The samples of the bytes that came since the last step, and whether more may be waiting; None once closed."""
        with self._lock:
            if self._closed.is_set() or self._file is None:
                return None
            file = self._file = self._current(self._file)
            data = b"" if file.records.backlog else file.read()  # the records read already first
            received = time.monotonic_ns()
        samples = self._samples(file, file.records.feed(data), received)
        return samples, len(data) == READ_BYTES or file.records.backlog

    def _current(self, file: _Reading) -> _Reading:
        """The file to read from: this one, or, when the recorder restarted, the new one at the path (once this one's
        last bytes are read), or this one from its start (when it shrank or was rewritten in place)."""
        if file.records.backlog:
            return file  # records read but not yet given come first
        try:
            info = os.stat(self.path)
        except FileNotFoundError:
            return file  # gone from the folder: what was written is still read, and a new file at the path is waited for
        if (info.st_dev, info.st_ino) != file.identity:
            if os.fstat(file.handle.fileno()).st_size > file.read_to:
                return file  # the old file's last bytes first
            replacement = self._open()
            if replacement is None:
                return file
            say(f"live: {shown(self.path)} was replaced (the recorder restarted?): reading the new file from its start")
            file.handle.close()
            return replacement
        why = file.rewritten()
        if why is None:
            return file
        say(f"live: {shown(self.path)} {why} (the recorder restarted?): reading it again from its start")
        file.handle.seek(0)
        restarted = _Reading(file.handle, str(self.path), self.where)
        return restarted

    def _samples(self, file: _Reading, records: list[tuple[int, McapRecord]], received: int) -> list[JointStateSample]:
        from mcap.records import Channel, Message, Schema

        samples: list[JointStateSample] = []
        for at, record in records:
            if self._closed.is_set():
                break  # a long backlog stops at close() too
            if isinstance(record, Message):
                topic = file.channels.get(record.channel_id)
                if topic is not None:
                    samples.append(self._sample(file, topic, record, at, received))
            elif isinstance(record, Schema):
                self._room(file, at, record.id, file.schemas)
                text = record.data[: MAX_SCHEMA_BYTES + 1] if record.name == JOINT_STATE else b""  # only JointState's is read
                file.schemas[record.id] = (record.name[:256], record.encoding[:64], text.decode("utf-8", "replace"))
            elif isinstance(record, Channel):
                self._room(file, at, record.id, file.channels)
                file.channels[record.id] = self._topic(file, record, at)
        file.messages += len(samples)
        return samples

    def _sample(self, file: _Reading, topic: _Topic, message: Message, at: int, received: int) -> JointStateSample:
        try:
            header_ns, names, positions = topic.decode(message.data)
        except UserError as error:  # the decoder names the topic; the file and the record's offset said here
            raise file.records.refused(at, error.message, error.where) from None
        return JointStateSample(topic.topic, names, positions, header_ns, message.log_time, message.publish_time, received)

    @staticmethod
    def _room(file: _Reading, at: int, key: int, kept: dict[int, Any]) -> None:
        """A file's Schema and Channel records are kept (a channel names its schema by id): up to DEFINITIONS_KEPT
        each, a stranger's file defining more is refused at the record."""
        if key not in kept and len(kept) >= DEFINITIONS_KEPT:
            raise file.records.refused(
                at, f"it defines more than {DEFINITIONS_KEPT:,} schemas or channels; a bag has one per type and topic"
            )

    def _topic(self, file: _Reading, channel: Channel, at: int) -> _Topic | None:
        """The decoder of a channel of a wanted topic (a wrong schema refused by name); None for another topic."""
        wanted = next((topic for topic in self.topics if same_topic(topic, channel.topic)), None)
        if wanted is None:
            if len(file.others) < OTHERS_SHOWN:
                file.others.add(channel.topic[:256])
            return None
        key = (channel.topic, channel.schema_id, channel.message_encoding)
        known = file.channels.get(channel.id)
        if known is not None and known.key == key:
            return known  # the summary section repeats the channels
        if channel.schema_id and channel.schema_id not in file.schemas:
            raise file.records.refused(
                at, f"the channel of '{shown(channel.topic)}' names schema {channel.schema_id}, which no record before it defines"
            )
        name, encoding, text = file.schemas.get(channel.schema_id, ("", "", ""))
        where = self.topics[wanted] or self.where or Where(self.path, 0)
        try:
            return _Topic(wanted, key, JointStateDecoder(wanted, name, encoding, text, channel.message_encoding, where))
        except UserError as error:  # not JointState, refused by name; the file and the channel's offset said here
            raise file.records.refused(at, error.message, error.where) from None

    def _unseen(self, file: _Reading) -> str:
        if any(file.channels.values()):
            return ""
        wanted = ", ".join(f"'{shown(topic)}'" for topic in self.topics)
        others = ", ".join(f"'{shown(topic)}'" for topic in sorted(file.others)) or "none"
        return f"; it has no channel on {wanted} (its topics: {others})"

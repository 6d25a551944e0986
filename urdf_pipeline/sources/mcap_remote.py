"""An MCAP file on S3, read as `validate` reads a local one, through ranged GETs and the `mcap` library (Rerun's reader
takes local paths only): the summary, and without `names` the topic's first message, within METADATA_BYTES. Every
chunk is read by mcap_chunks.py, never by the `mcap` library's readers, which inflate a chunk as big as it says.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import IO

from ..errors import UserError, Where
from ..plan import RemoteObject
from .joint_state_cdr import read_joint_state
from .mcap_chunks import InflationBudget, McapRefused, chunk_records, read_chunk_at, read_summary, refusal, require_library, short_reason
from .mcap_probe import topic_entity

METADATA_BYTES = 64 << 20  # the summary and the first message's chunk, at most (a chunk is a few MB by default)
METADATA_BLOCK = 64 << 10  # bytes a ranged GET fetches at least: the magic, the footer, the summary's pieces


@dataclass(frozen=True)
class SchemaInfo:
    name: str


@dataclass(frozen=True)
class ChannelInfo:
    """What `validate` reads of a channel, as Rerun's `McapChannelInfo` gives it for a local file."""

    topic: str
    schema: SchemaInfo | None
    message_encoding: str
    message_count: int | None


@dataclass(frozen=True)
class SummaryInfo:
    """The summary's channels and last log time, as Rerun's `McapReader(path).info()` gives them for a local file."""

    channels: tuple[ChannelInfo, ...]
    message_end_time_ns: int | None


def late_messages(stream: IO[bytes], topic: str, start: int) -> int:
    """How many messages of `topic` are logged at or after `start`: only the chunks whose time range reaches it and
    that may hold the topic (the summary's chunk index) are read, each inflated within its bounds (McapRefused)."""
    from mcap.records import Message

    summary = read_summary(stream)
    if summary is None or not summary.chunk_indexes:
        raise ValueError("no chunk index to find the late messages by")
    channels = {key for key, channel in summary.channels.items() if topic_entity(channel.topic) == topic_entity(topic)}
    count, budget = 0, InflationBudget()
    for index in summary.chunk_indexes:
        if index.message_end_time < start or (index.message_index_offsets and not channels & index.message_index_offsets.keys()):
            continue
        records = chunk_records(read_chunk_at(stream, index.chunk_start_offset), index.chunk_start_offset, budget)
        count += sum(1 for record in records if isinstance(record, Message) and record.channel_id in channels and record.log_time >= start)
    return count


class RemoteMcap:
    """One remote MCAP file, open for its metadata: the summary, read once, and the first message of a topic."""

    def __init__(self, remote: RemoteObject, stream: IO[bytes], where: Where | None) -> None:
        self.remote = remote
        self.stream = stream
        self.where = where
        try:
            self.summary = read_summary(stream)
        except McapRefused as error:
            raise refusal(remote.url, error, where) from None
        except UserError:
            raise
        except Exception as exc:  # the mcap library's errors on a file that is no MCAP, or a damaged one
            raise UserError(f"cannot read MCAP file {remote.url}: {short_reason(exc)}", where) from None
        if self.summary is None:
            raise UserError(
                f"MCAP file {remote.url} has no summary section (the index at its end, which a finished recording has): it cannot be "
                "checked without reading it all; rewrite it with `mcap recover`, or download it and name the local file",
                where,
            )

    def info(self) -> SummaryInfo:
        summary = self.summary
        assert summary is not None
        counts = summary.statistics.channel_message_counts if summary.statistics is not None else None
        channels = tuple(
            ChannelInfo(
                channel.topic,
                SchemaInfo(summary.schemas[channel.schema_id].name) if channel.schema_id in summary.schemas else None,
                channel.message_encoding,
                counts.get(channel_id, 0) if counts is not None else None,
            )
            for channel_id, channel in sorted(summary.channels.items())
        )
        end = summary.statistics.message_end_time if summary.statistics is not None and summary.statistics.message_count else None
        return SummaryInfo(channels, end)

    def first_names(self, topics: list[str]) -> tuple[str, ...] | None:
        """The names of the first message on `topics` in file order, None when there is none. Only the chunks that
        may hold one are read (by the chunk index), in file order, until one does: one chunk, within METADATA_BYTES."""
        from ..remote import OverBudget

        assert self.summary is not None
        if not self.summary.chunk_indexes:
            raise UserError(
                f"MCAP file {self.remote.url} has no chunk index: its first message cannot be found without reading it all; "
                "give the names with names: [...]",
                self.where,
            )
        try:
            data = self._first_message(topics)
            return None if data is None else read_joint_state(bytes(data))[1]
        except McapRefused as error:
            raise refusal(self.remote.url, error, self.where) from None
        except OverBudget:
            raise UserError(
                f"the first message on {topics[0]} of MCAP file {self.remote.url} is not within its first {METADATA_BYTES >> 20} MB "
                "of chunks; give the names with names: [...]",
                self.where,
            ) from None
        except UserError:
            raise
        except Exception as exc:  # a chunk that does not decompress, a message that is no JointState
            raise UserError(
                f"MCAP file {self.remote.url} is corrupt: {short_reason(exc)} (reading topic '{topics[0]}')", self.where
            ) from None

    def _first_message(self, topics: list[str]) -> bytes | None:
        from mcap.records import Message

        assert self.summary is not None
        budget = InflationBudget()
        channels = {channel_id for channel_id, channel in self.summary.channels.items() if channel.topic in topics}
        for index in sorted(self.summary.chunk_indexes, key=lambda chunk: chunk.chunk_start_offset):  # one per chunk
            if index.message_index_offsets and not channels & index.message_index_offsets.keys():
                continue  # its message index says it holds none of the topic's messages
            at = index.chunk_start_offset
            for record in chunk_records(read_chunk_at(self.stream, at), at, budget):
                if isinstance(record, Message) and record.channel_id in channels:
                    return bytes(record.data)
        return None

    def late_messages(self, topic: str, start: int) -> int:
        try:
            return late_messages(self.stream, topic, start)
        except McapRefused as error:
            raise refusal(self.remote.url, error, self.where) from None


@contextmanager
def remote_mcap(remote: RemoteObject, where: Where | None) -> Iterator[RemoteMcap]:
    """The file's metadata through ranged GETs (at most METADATA_BYTES in all)."""
    require_library(where)  # said before any request
    from ..remote import open_range

    with open_range(remote, where, block=METADATA_BLOCK, max_bytes=METADATA_BYTES) as stream:
        yield RemoteMcap(remote, stream, where)

"""The complete records of an MCAP file that is still being written: its bytes come in pieces, a record whose bytes
are not all there yet waits for the next piece. The framing (the magic, then records of a uint8 opcode and a uint64
little-endian length) is read here; each record's content is parsed by the `mcap` library's record classes, a chunk's
records by the sources' `chunk_records`, which every MCAP chunk the tool reads goes through.

Everything is bounded before it is allocated (docs/security.md): a record longer than FOLLOWED_RECORD_BYTES is refused
from its length, before its bytes are kept, and `chunk_records` inflates a chunk only within FOLLOWED_CHUNK_BYTES (every
message of a chunk is decoded in one step, at about twelve bytes of memory per byte: 16 MiB keeps `live` within 400 MB).
"""

from __future__ import annotations

import struct
from io import BytesIO
from typing import TYPE_CHECKING

from ..errors import UserError, Where, shown
from ..sources import HEAD, MAGIC, InflationBudget, McapRefused, chunk_records, parsed_chunk, refusal, short_reason

if TYPE_CHECKING:
    from mcap.records import McapRecord

FOLLOWED_CHUNK_BYTES = 16 << 20  # recorders write chunks of 768 KiB (ros2 bag) to 4 MiB, bigger only around one big message
FOLLOWED_RECORD_BYTES = FOLLOWED_CHUNK_BYTES + (1 << 20)  # a chunk's compressed bytes are a little over its size, at worst


class RecordSplitter:
    """Feed it the file's bytes in order (`feed`); it returns the records completed so far, each with the offset of
    its record in the file (for a chunk's records, the chunk's). The Schema, Channel, Message and Footer records are
    parsed (chunks opened), the rest skipped; nothing after the Footer is read."""

    def __init__(self, name: str, where: Where | None) -> None:
        self.name, self.where = name, where
        self.pending = bytearray()  # bytes read but not yet part of a complete record
        self.offset = 0  # the file offset of pending[0]
        self.footer = False
        self.budget = InflationBudget()  # what this reading of the file may inflate in all
        self.backlog = False  # whole records wait in `pending`: feed again before reading more

    def feed(self, data: bytes) -> list[tuple[int, McapRecord]]:
        """The records `data` completes, from the first not yet given; at most FOLLOWED_CHUNK_BYTES of them inflated
        (then `backlog` says more are waiting), so one step never holds more than one big chunk's messages."""
        self.backlog = False
        if self.footer:
            return []
        self.pending += data
        if self.offset == 0 and not self._past_magic():
            return []
        records: list[tuple[int, McapRecord]] = []
        position, pending, inflated = 0, self.pending, self.budget.inflated
        while not self.footer and len(pending) - position >= HEAD.size:
            if self.budget.inflated - inflated >= FOLLOWED_CHUNK_BYTES:
                self.backlog = True
                break
            opcode, length = HEAD.unpack_from(pending, position)
            at = self.offset + position
            if length > FOLLOWED_RECORD_BYTES:
                raise self.refused(
                    at,
                    f"a record (opcode {opcode:#04x}) of {length:,} bytes, beyond {FOLLOWED_RECORD_BYTES >> 20} MiB: the file is damaged",
                )
            end = position + HEAD.size + length
            if end > len(pending):
                break  # its bytes are not all written yet
            with memoryview(pending) as view:  # one copy of the record's bytes, not two
                content = bytes(view[position + HEAD.size : end])
            records.extend((at, record) for record in self._parsed(opcode, content, at))
            position = end
        del pending[:position]
        self.offset += position
        return records

    def refused(self, at: int, why: str, where: Where | None = None) -> UserError:
        """The error of the record at file offset `at` (`where`: the config's place, when not the file's source)."""
        return refusal(self.name, McapRefused(at, why), where or self.where)

    def _past_magic(self) -> bool:
        """Whether the magic is complete and right (then it is dropped); refused as soon as a byte of it is wrong."""
        head = bytes(self.pending[: len(MAGIC)])
        if not MAGIC.startswith(head):
            raise self.refused(0, f"not an MCAP file: it starts with {shown(repr(head))}, not the MCAP magic {MAGIC!r}")
        if len(head) < len(MAGIC):
            return False
        del self.pending[: len(MAGIC)]
        self.offset = len(MAGIC)
        return True

    def _parsed(self, opcode: int, content: bytes, at: int) -> list[McapRecord]:
        from mcap.data_stream import ReadDataStream
        from mcap.exceptions import EndOfFile
        from mcap.opcode import Opcode
        from mcap.records import Channel, Footer, Message, Schema

        stream = ReadDataStream(BytesIO(content))
        try:
            if opcode == Opcode.CHUNK:
                return chunk_records(parsed_chunk(content, at), at, self.budget, FOLLOWED_CHUNK_BYTES)
            if opcode == Opcode.MESSAGE:
                return [Message.read(stream, len(content))]
            if opcode == Opcode.FOOTER:
                self.footer = True
                return [Footer.read(stream)]
            if opcode == Opcode.SCHEMA:
                return [Schema.read(stream)]
            if opcode == Opcode.CHANNEL:
                return [Channel.read(stream)]
            return []  # the header, indexes, statistics, attachments, metadata: nothing a live view reads
        except McapRefused as error:
            raise self.refused(error.at, error.why) from None
        except (EndOfFile, struct.error):  # a field read past the record's end
            raise self.refused(
                at, f"a record (opcode {opcode:#04x}) whose content ends before its fields do: the file is damaged"
            ) from None
        except Exception as exc:  # the mcap library's and the decompressors' assorted errors on damage
            raise self.refused(at, f"a damaged record (opcode {opcode:#04x}): {short_reason(exc)}") from None

"""The complete records of an MCAP file that is still being written: its bytes come in pieces, a record whose bytes
are not all there yet waits for the next piece. The framing (the magic, then records of a uint8 opcode and a uint64
little-endian length) is read here; each record's content is parsed by the `mcap` library's record classes, a chunk's
records by its `breakup_chunk`.

Everything is bounded before it is allocated: a record longer than MAX_RECORD_BYTES, or a chunk stating more than
MAX_CHUNK_BYTES uncompressed, is refused as damage, and a chunk is inflated at most to its stated size (a zstd frame
header or an lz4 stream that says more is no reason to allocate more), so a damaged or hostile file costs a located
error, never a traceback or the machine's memory.
"""

from __future__ import annotations

import struct
from dataclasses import replace
from io import BytesIO
from typing import TYPE_CHECKING

from ..errors import UserError, Where, shown

if TYPE_CHECKING:
    from mcap.records import Chunk, McapRecord

MAGIC = b"\x89MCAP0\r\n"
HEAD = struct.Struct("<BQ")  # a record's opcode and content length
MAX_RECORD_BYTES = 256 << 20  # a chunk is a few MB (the writers' defaults are 1 MiB and less); a JointState far less
MAX_CHUNK_BYTES = 256 << 20
COMPRESSIONS = ("", "zstd", "lz4")


class RecordSplitter:
    """Feed it the file's bytes in order (`feed`); it returns the records completed so far, each with the offset of
    its record in the file (for a chunk's records, the chunk's). The Schema, Channel, Message and Footer records are
    parsed (chunks opened), the rest skipped; nothing after the Footer is read."""

    def __init__(self, name: str, where: Where | None) -> None:
        self.name, self.where = name, where
        self.pending = bytearray()  # bytes read but not yet part of a complete record
        self.offset = 0  # the file offset of pending[0]
        self.footer = False

    def feed(self, data: bytes) -> list[tuple[int, McapRecord]]:
        if self.footer:
            return []
        self.pending += data
        if self.offset == 0 and not self._past_magic():
            return []
        records: list[tuple[int, McapRecord]] = []
        position, pending = 0, self.pending
        while not self.footer and len(pending) - position >= HEAD.size:
            opcode, length = HEAD.unpack_from(pending, position)
            at = self.offset + position
            if length > MAX_RECORD_BYTES:
                raise self.refused(
                    at, f"a record (opcode {opcode:#04x}) of {length} bytes, beyond {MAX_RECORD_BYTES >> 20} MiB: the file is damaged"
                )
            end = position + HEAD.size + length
            if end > len(pending):
                break  # its bytes are not all written yet
            records.extend((at, record) for record in self._parsed(opcode, bytes(pending[position + HEAD.size : end]), at))
            position = end
        del pending[:position]
        self.offset += position
        return records

    def refused(self, at: int, why: str, where: Where | None = None) -> UserError:
        """The error of the record at file offset `at` (`where`: the config's place, when not the file's source)."""
        return UserError(f"MCAP file {shown(self.name)}, byte {at}: {why}", where or self.where)

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
        from mcap.records import Channel, Chunk, Footer, Message, Schema

        stream = ReadDataStream(BytesIO(content))
        try:
            if opcode == Opcode.CHUNK:
                return self._chunk_records(Chunk.read(stream), at)
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
        except UserError:
            raise
        except (EndOfFile, struct.error):  # a field read past the record's end
            raise self.refused(
                at, f"a record (opcode {opcode:#04x}) whose content ends before its fields do: the file is damaged"
            ) from None
        except Exception as exc:  # noqa: BLE001 - the mcap library's and the decompressors' assorted errors on damage
            raise self.refused(at, f"a damaged record (opcode {opcode:#04x}): {shown(_reason(exc))}") from None

    def _chunk_records(self, chunk: Chunk, at: int) -> list[McapRecord]:
        from mcap.stream_reader import breakup_chunk

        if chunk.compression not in COMPRESSIONS:
            raise self.refused(at, f"a chunk compressed with {shown(repr(chunk.compression))}; MCAP chunks are zstd, lz4 or uncompressed")
        if chunk.uncompressed_size > MAX_CHUNK_BYTES:
            raise self.refused(
                at, f"a chunk of {chunk.uncompressed_size} bytes uncompressed, beyond {MAX_CHUNK_BYTES >> 20} MiB: the file is damaged"
            )
        data = _inflated(chunk)
        if len(data) != chunk.uncompressed_size:
            more = "more" if len(data) > chunk.uncompressed_size else f"{len(data)}"
            raise self.refused(
                at, f"a chunk stating {chunk.uncompressed_size} bytes uncompressed inflates to {more} bytes: the file is damaged"
            )
        return breakup_chunk(replace(chunk, compression="", data=data), validate_crc=True)


def _inflated(chunk: Chunk) -> bytes:
    """The chunk's records, at most one byte more than its stated size (so a longer one is seen, not allocated)."""
    limit = chunk.uncompressed_size + 1
    if chunk.compression == "zstd":
        import zstandard

        with zstandard.ZstdDecompressor().stream_reader(chunk.data, read_across_frames=True) as reader:
            pieces, size = [], 0
            while size < limit and (piece := reader.read(limit - size)):
                pieces.append(piece)
                size += len(piece)
            return b"".join(pieces)
    if chunk.compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]  # no stubs; the mcap library depends on it

        data: bytes = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=limit)
        return data
    return chunk.data


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__

"""Every MCAP chunk the tool inflates is inflated here, bounded by the bytes it produces, never by what the chunk, its
index or its zstd or lz4 frame states: a few KB of either can state anything, and be gigabytes of zeros (the bounds:
security.md#mcap-files, MAX_CHUNK_BYTES and `InflationBudget` below).

The `mcap` library's readers inflate a chunk whole, as big as it says; Rerun's reader inflates every chunk of a file
whatever topic it is asked for, and spins for minutes on one in the summary section. So neither ever gets a chunk this
module has not inflated first: the summary (`read_summary`: a chunk in it is refused), a chunk's records
(`chunk_records`, `read_chunk_at`), and, before Rerun's reader reads a file, every chunk of it once (`check_chunks`),
each one the summary's index points at included, so that the two kinds of reader cannot be shown two files.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import IO, TYPE_CHECKING, cast

from ..errors import UserError, Where, quoted, shown

if TYPE_CHECKING:
    from mcap.records import Chunk, McapRecord
    from mcap.summary import Summary

MAX_CHUNK_BYTES = 64 << 20  # writers' chunks are 1-4 MiB (ros2 bag: 768 KiB), bigger only around one big message
MAX_RECORD_BYTES = MAX_CHUNK_BYTES + (1 << 20)  # a chunk's record: its compressed bytes (a little over its size, at worst)
RATIO = 1000  # a bag of a 30-joint robot at rest, its values all zero, sent at 1 kHz: 135
FREE_BYTES = 256 << 20  # inflated before RATIO applies
MAGIC = b"\x89MCAP0\r\n"
HEAD = struct.Struct("<BQ")  # a record's opcode and content length
CHUNK, FOOTER = 0x06, 0x02
FOOTER_BYTES = HEAD.size + 20  # the footer record: summary start, summary offset start, summary CRC
COMPRESSIONS = ("", "zstd", "lz4")
INSTALL = "pip install mcap"


class McapRefused(ValueError):
    """A record of an MCAP file this tool will not read (a chunk that inflates beyond its bound or its stated size,
    one that does not inflate, a damaged record), at byte `at` of the file, because `why`."""

    def __init__(self, at: int, why: str) -> None:
        super().__init__(f"byte {at}: {why}")
        self.at, self.why = at, why


def inflate(compression: str, data: bytes | memoryview, limit: int) -> bytes | bytearray:
    """`data` inflated, at most `limit` + 1 bytes of it (so a longer one is seen, never allocated)."""
    if compression == "zstd":
        import zstandard

        inflated = bytearray(limit + 1)  # zstd's own one-shot call would allocate what the frame header says
        size = 0
        with (
            memoryview(inflated) as view,
            zstandard.ZstdDecompressor(max_window_size=MAX_CHUNK_BYTES).stream_reader(data, read_across_frames=True) as reader,
        ):
            while size <= limit and (count := reader.readinto(view[size:])):
                size += count
        del inflated[size:]
        return inflated
    if compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]  # no stubs; the mcap library depends on it

        framed: bytes = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=limit + 1)
        return framed
    return bytes(data[: limit + 1])


class InflationBudget:
    """What one reading of a file may inflate in all: FREE_BYTES, plus RATIO times the compressed chunk bytes it read.
    Counted on the sizes chunks state, before each is inflated: each must then produce exactly that."""

    def __init__(self) -> None:
        self.compressed = 0
        self.inflated = 0

    def take(self, chunk: Chunk, at: int) -> None:
        self.compressed += len(chunk.data)
        self.inflated += chunk.uncompressed_size
        if self.inflated > FREE_BYTES + RATIO * self.compressed:
            raise McapRefused(
                at,
                f"chunks that inflate to {self.inflated:,} bytes from {self.compressed:,}, more than {RATIO} times their size beyond "
                f"the first {FREE_BYTES >> 20} MiB: a decompression bomb",
            )


def chunk_content(chunk: Chunk, at: int, budget: InflationBudget, limit: int = MAX_CHUNK_BYTES) -> bytes | bytearray:
    """The records of the chunk whose record starts at byte `at`: inflated within `limit`, its stated size, which it
    must fill exactly, and what is left of the reading's `budget`; its CRC checked when it states one."""
    if chunk.compression not in COMPRESSIONS:
        raise McapRefused(at, f"a chunk compressed with {quoted(chunk.compression)}; MCAP chunks are zstd, lz4 or uncompressed")
    stated = chunk.uncompressed_size
    if stated > limit:
        raise McapRefused(
            at,
            f"a chunk stating {stated:,} bytes uncompressed, beyond the {limit >> 20} MiB a chunk may hold: a damaged file, or a decompression bomb",
        )
    budget.take(chunk, at)
    try:
        data = inflate(chunk.compression, chunk.data, stated)
    except Exception as exc:  # zstandard's and lz4's errors on bytes that are no frame
        raise McapRefused(at, f"a {chunk.compression} chunk that does not inflate ({short_reason(exc)}): the file is damaged") from None
    if len(data) != stated:
        produced = "more" if len(data) > stated else f"{len(data):,}"
        raise McapRefused(at, f"a chunk stating {stated:,} bytes uncompressed inflates to {produced} bytes: the file is damaged")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise McapRefused(at, "a chunk whose records do not match its CRC: the file is damaged")
    return data


def chunk_records(chunk: Chunk, at: int, budget: InflationBudget, limit: int = MAX_CHUNK_BYTES) -> list[McapRecord]:
    """The Schema, Channel and Message records of the chunk at byte `at`, inflated by `chunk_content`."""
    from mcap.stream_reader import breakup_chunk

    content = chunk_content(chunk, at, budget, limit)
    try:
        records = cast(bytes, content)  # a bytearray reads as bytes do here (BytesIO), without a copy
        return breakup_chunk(replace(chunk, compression="", data=records, uncompressed_crc=0))
    except Exception as exc:  # the mcap library's errors on records that end before their fields
        raise McapRefused(at, f"a chunk whose records are damaged ({short_reason(exc)})") from None


def read_record(stream: IO[bytes], at: int, opcodes: tuple[int, ...] = ()) -> tuple[int, bytes]:
    """The opcode and content of the record at byte `at` (one of `opcodes`, when given), within MAX_RECORD_BYTES."""
    stream.seek(at)
    head = stream.read(HEAD.size)
    if len(head) < HEAD.size:
        raise McapRefused(at, "a record that ends past the end of the file")
    opcode, length = HEAD.unpack(head)
    if opcodes and opcode not in opcodes:
        raise McapRefused(at, f"a record of opcode {opcode:#04x} where the file's index points at a chunk: the file is damaged")
    if length > MAX_RECORD_BYTES:
        raise McapRefused(
            at, f"a record (opcode {opcode:#04x}) of {length:,} bytes, beyond {MAX_RECORD_BYTES >> 20} MiB: the file is damaged"
        )
    content = stream.read(length)
    if len(content) < length:
        raise McapRefused(at, f"a record (opcode {opcode:#04x}) that ends past the end of the file")
    return opcode, content


def parsed_chunk(content: bytes | memoryview, at: int) -> Chunk:
    """A chunk record's fields (its data still compressed)."""
    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk

    try:
        return Chunk.read(ReadDataStream(io.BytesIO(content)))
    except Exception as exc:  # a field read past the record's end
        raise McapRefused(
            at, f"a chunk record whose content ends before its fields do ({short_reason(exc)}): the file is damaged"
        ) from None


def read_chunk_at(stream: IO[bytes], at: int) -> Chunk:
    """The chunk whose record starts at byte `at` (as the summary's chunk index says), not yet inflated."""
    return parsed_chunk(read_record(stream, at, (CHUNK,))[1], at)


def read_summary(stream: IO[bytes]) -> Summary | None:
    """The summary section (schemas, channels, statistics, chunk and other indexes), None when the file has none.
    Read record by record within MAX_RECORD_BYTES each; a chunk there is refused, never inflated (the `mcap`
    library's `get_summary` would inflate it whole, Rerun's reader would spin on it for minutes)."""
    from mcap.data_stream import ReadDataStream
    from mcap.opcode import Opcode
    from mcap.records import AttachmentIndex, Channel, ChunkIndex, MetadataIndex, Schema, Statistics
    from mcap.summary import Summary

    stream.seek(0)
    if stream.read(len(MAGIC)) != MAGIC:
        raise McapRefused(0, "not an MCAP file: it does not start with the MCAP magic")
    end = stream.seek(0, io.SEEK_END)
    if end < 2 * len(MAGIC) + FOOTER_BYTES:
        raise McapRefused(end, "an MCAP file cut short: it ends before its footer")
    stream.seek(end - len(MAGIC) - FOOTER_BYTES)
    tail = stream.read(FOOTER_BYTES + len(MAGIC))
    opcode, length = HEAD.unpack_from(tail)
    if tail[-len(MAGIC) :] != MAGIC or opcode != FOOTER or length != FOOTER_BYTES - HEAD.size:
        raise McapRefused(end, "an MCAP file without its footer (still being written, or cut short)")
    summary_start = struct.unpack_from("<Q", tail, HEAD.size)[0]
    if summary_start == 0:
        return None
    readers: dict[int, Callable[[ReadDataStream], object]] = {
        Opcode.SCHEMA: Schema.read,
        Opcode.CHANNEL: Channel.read,
        Opcode.STATISTICS: Statistics.read,
        Opcode.CHUNK_INDEX: ChunkIndex.read,
        Opcode.ATTACHMENT_INDEX: AttachmentIndex.read,
        Opcode.METADATA_INDEX: MetadataIndex.read,
    }
    summary, at = Summary(), summary_start
    footer_at = end - len(MAGIC) - FOOTER_BYTES
    while at < footer_at:
        opcode, content = read_record(stream, at)
        if opcode == CHUNK:
            raise McapRefused(at, "a chunk in the summary section, where none belongs: the file is damaged")
        read = readers.get(opcode)
        if read is not None:
            try:
                record = read(ReadDataStream(io.BytesIO(content)))
            except Exception as exc:  # a field read past the record's end
                raise McapRefused(
                    at, f"a summary record (opcode {opcode:#04x}) whose content ends before its fields do ({short_reason(exc)})"
                ) from None
            _keep(summary, record)
        at += HEAD.size + len(content)
    return summary


def _keep(summary: Summary, record: object) -> None:
    from mcap.records import AttachmentIndex, Channel, ChunkIndex, MetadataIndex, Schema, Statistics

    if isinstance(record, Schema):
        summary.schemas[record.id] = record
    elif isinstance(record, Channel):
        summary.channels[record.id] = record
    elif isinstance(record, Statistics):
        summary.statistics = record
    elif isinstance(record, ChunkIndex):
        summary.chunk_indexes.append(record)
    elif isinstance(record, AttachmentIndex):
        summary.attachment_indexes.append(record)
    elif isinstance(record, MetadataIndex):
        summary.metadata_indexes.append(record)


_CHECKED: set[tuple[str, int, int, int, int]] = set()  # files whose every chunk was inflated once, by identity


def check_chunks(path: Path) -> None:
    """Inflate every chunk of the file once, within its bounds, and drop it: record by record from the start, then each
    chunk the summary's index points at, which must be one of those, stating what it states. A file checked (and
    unchanged since: device, inode, size, modification time) is not checked again."""
    info = path.stat()
    key = (str(path), info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns)
    if key in _CHECKED:
        return
    with path.open("rb") as stream:
        summary = read_summary(stream)
        chunks: dict[int, tuple[str, int]] = {}
        budget = InflationBudget()
        at = len(MAGIC)
        stream.seek(at)
        while (head := stream.read(HEAD.size)) and len(head) == HEAD.size:
            opcode, length = HEAD.unpack(head)
            if opcode == FOOTER:
                break
            if opcode == CHUNK:
                chunk = parsed_chunk(read_record(stream, at)[1], at)
                chunk_content(chunk, at, budget)
                chunks[at] = (chunk.compression, chunk.uncompressed_size)
            at += HEAD.size + length
            stream.seek(at)
        for index in summary.chunk_indexes if summary is not None else ():
            if chunks.get(index.chunk_start_offset) != (index.compression, index.uncompressed_size):
                raise McapRefused(
                    index.chunk_start_offset,
                    f"the summary's chunk index names a {index.compression or 'plain'} chunk of {index.uncompressed_size:,} bytes here, "
                    "which the records of the file do not hold: the file is damaged",
                )
    _CHECKED.add(key)


def refusal(name: str, error: McapRefused, where: Where | None) -> UserError:
    """The one line of a refused record: the file (its path or URL), the record's byte offset, why."""
    return UserError(f"MCAP file {shown(name)}, byte {error.at}: {error.why}", where)


def require_library(where: Where | None) -> None:
    """The `mcap` library (and the zstandard and lz4 it depends on) reads every chunk: said before any file is read."""
    try:
        import lz4.frame  # noqa: F401
        import mcap.records  # noqa: F401
        import zstandard  # noqa: F401
    except ImportError:
        raise UserError(
            f"MCAP files are read with the mcap library (its zstd and lz4 readers bound every chunk): {INSTALL}", where
        ) from None


def short_reason(exc: BaseException) -> str:
    """The first line of a library's error, as a message shows it (escaped, bounded)."""
    text = str(exc).strip().splitlines()
    return shown(text[0]) if text else type(exc).__name__

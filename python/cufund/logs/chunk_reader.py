"""Messages of an indexed MCAP file in (log time, sequence) order, read chunk by chunk.

The ``mcap`` package's reader merges chunks through a heap of Python objects with Python comparisons; here a
chunk is decompressed (its CRC checked), its records are split with ``struct``, and its messages go into a heap of
plain tuples (compared in C). A chunk is read only once the merge reaches its start time, so memory holds the
chunks that overlap in time, not the file.
"""

from __future__ import annotations

import heapq
import struct
import zlib
from collections.abc import Iterator
from typing import IO, Any

__all__ = ["iter_chunk_messages"]

_MESSAGE = 0x05
_CHUNK = 0x06
_RECORD = struct.Struct("<BQ")
_MESSAGE_HEADER = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
_CHUNK_HEADER = struct.Struct("<BQQQQII")  # opcode, length, start, end, uncompressed size, crc, compression length


class ChunkError(ValueError):
    """A chunk that does not decompress, fails its CRC or holds a malformed record."""


MAX_CHUNK_BYTES = 1 << 26
"""Largest uncompressed chunk read, 64 MiB (cufund writes chunks of about 1 MiB; a chunk claiming more is damage
or a decompression bomb: nothing is allocated for it)."""


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    """``data`` decompressed, never to more than ``size`` bytes (the size the chunk declares)."""
    if compression == "":
        return data
    if compression == "lz4":
        import lz4.frame

        decompressor = lz4.frame.LZ4FrameDecompressor()
        out = decompressor.decompress(data, max_length=size)
        if not decompressor.eof:
            raise ChunkError(f"the lz4 frame holds more than the {size} bytes the chunk declares, or is cut short")
        return out
    if compression == "zstd":
        import zstandard

        reader = zstandard.ZstdDecompressor().stream_reader(data)
        out = reader.read(size + 1)
        if len(out) > size:
            raise ChunkError(f"the zstd frame holds more than the {size} bytes the chunk declares")
        return out
    raise ChunkError(f"unsupported chunk compression {compression[:64]!r}")


def _chunk_messages(stream: IO[bytes], index: Any, wanted: set[int], order: int) -> list[tuple[Any, ...]]:
    """(log time, sequence, order, position, channel id, publish time, data) of the wanted messages of a chunk."""
    stream.seek(index.chunk_start_offset)
    record = stream.read(index.chunk_length)
    if len(record) != index.chunk_length:
        raise ChunkError(f"the chunk at byte {index.chunk_start_offset} is cut short")
    opcode, _, _, _, size, crc, name_length = _CHUNK_HEADER.unpack_from(record, 0)
    if opcode != _CHUNK:
        raise ChunkError(f"no chunk at byte {index.chunk_start_offset} (opcode {opcode:#x})")
    if size > MAX_CHUNK_BYTES:
        raise ChunkError(
            f"the chunk at byte {index.chunk_start_offset} claims {size} bytes uncompressed, more "
            f"than {MAX_CHUNK_BYTES}"
        )
    at = _CHUNK_HEADER.size
    compression = record[at : at + name_length].decode()
    (data_length,) = struct.unpack_from("<Q", record, at + name_length)
    at += name_length + 8
    try:
        raw = _decompress(compression, record[at : at + data_length], size)
    except ChunkError:
        raise
    except Exception as exc:
        raise ChunkError(f"the chunk at byte {index.chunk_start_offset} does not decompress: {exc}") from exc
    if len(raw) != size or (crc and zlib.crc32(raw) != crc):
        raise ChunkError(f"the chunk at byte {index.chunk_start_offset} fails its CRC or size check")
    out = []
    at, end = 0, len(raw)
    view = memoryview(raw)
    try:
        while at < end:
            opcode, length = _RECORD.unpack_from(raw, at)
            body = at + 9
            at = body + length
            if at > end:
                raise ChunkError(f"a record overruns the chunk at byte {index.chunk_start_offset}")
            if opcode == _MESSAGE:
                if length < _MESSAGE_HEADER.size:
                    raise ChunkError(
                        f"a message record of {length} bytes in the chunk at byte {index.chunk_start_offset}"
                    )
                channel, sequence, log, publish = _MESSAGE_HEADER.unpack_from(raw, body)
                if channel in wanted:
                    out.append((log, sequence, order, body, channel, publish, view[body + 22 : at]))
    except struct.error as exc:
        raise ChunkError(f"a malformed record in the chunk at byte {index.chunk_start_offset}: {exc}") from exc
    return out


def iter_chunk_messages(stream: IO[bytes], chunk_indexes: list[Any], wanted: set[int]) -> Iterator[tuple[Any, ...]]:
    """(log time, sequence, ..., channel id, publish time, data) of every wanted message, in log-time order, ties
    by sequence number then position in the file."""
    chunks = sorted(
        (c for c in chunk_indexes if wanted & set(c.message_index_offsets)),
        key=lambda c: (c.message_start_time, c.chunk_start_offset),
    )
    heap: list[tuple[Any, ...]] = []
    next_chunk = 0
    while True:
        while next_chunk < len(chunks) and (not heap or chunks[next_chunk].message_start_time <= heap[0][0]):
            for item in _chunk_messages(stream, chunks[next_chunk], wanted, next_chunk):
                heapq.heappush(heap, item)
            next_chunk += 1
        if not heap:
            return
        yield heapq.heappop(heap)

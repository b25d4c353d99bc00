"""What a log without a summary (its run was killed mid-write) still holds: a scan of its records from the start.

The logger writes the header, the ``cufund`` metadata, then schemas, channels and chunks as a run goes, and the
summary (channels, chunk indexes) only when closed. :func:`scan_records` walks the records one by one (reading
the bodies of channels only; a chunk's header, then a seek past it) and stops at the first record that the file
ends inside, at the data end or at the footer: the complete chunks found are indexed as the summary would have
indexed them, so that :func:`cufund.logs.read_mcap` reads them like any log's.
"""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass, field
from typing import IO, Any

from mcap.data_stream import ReadDataStream
from mcap.records import Channel, ChunkIndex

__all__ = ["MAGIC", "Recovered", "scan_records"]

MAGIC = b"\x89MCAP0\r\n"
_RECORD = struct.Struct("<BQ")
_CHUNK_START = struct.Struct("<QQQII")  # message start, end, uncompressed size, crc, compression name length
_HEADER, _CHANNEL, _CHUNK, _DATA_END, _FOOTER = 0x01, 0x04, 0x06, 0x0F, 0x02
_MAX_CHANNEL_RECORD = 1 << 20
"""A channel record longer than this is damage, not a channel: the scan stops there."""


@dataclass
class Recovered:
    """The channels and complete chunks of a log without a summary; ``end``: the byte after the last complete
    record."""

    channels: dict[int, Any] = field(default_factory=dict)
    chunks: list[Any] = field(default_factory=list)
    end: int = len(MAGIC)


def scan_records(stream: IO[bytes]) -> Recovered:
    """Scans ``stream`` (positioned after the leading magic) to its last complete record."""
    out = Recovered()
    size = stream.seek(0, io.SEEK_END)
    pos = len(MAGIC)
    stream.seek(pos)
    while True:
        head = stream.read(_RECORD.size)
        if len(head) < _RECORD.size:
            break
        opcode, length = _RECORD.unpack(head)
        body = pos + _RECORD.size
        if pos == len(MAGIC) and opcode != _HEADER:
            raise ValueError(f"the record after the magic has opcode {opcode:#x}, not a header")
        if opcode == 0x00 or opcode > 0x7F:  # reserved / private opcodes: not a record, so the log ends here (a
            break  # power loss leaves a zero-filled tail after the last complete record)
        if length > size - body or opcode in (_DATA_END, _FOOTER):
            break  # cut inside this record, or the end of the data
        if opcode == _CHANNEL:
            if length > _MAX_CHANNEL_RECORD:
                break
            channel = Channel.read(ReadDataStream(io.BytesIO(stream.read(length))))
            out.channels[channel.id] = channel
        elif opcode == _CHUNK:
            if length < _CHUNK_START.size + 8:
                break
            start, end, uncompressed, _, name_length = _CHUNK_START.unpack(stream.read(_CHUNK_START.size))
            if name_length > 64 or _CHUNK_START.size + name_length + 8 > length:
                break
            compression = stream.read(name_length).decode("utf-8", "replace")
            out.chunks.append(
                ChunkIndex(
                    message_start_time=start,
                    message_end_time=end,
                    chunk_start_offset=pos,
                    chunk_length=_RECORD.size + length,
                    message_index_offsets={},
                    message_index_length=0,
                    compression=compression,
                    compressed_size=length - _CHUNK_START.size - name_length - 8,
                    uncompressed_size=uncompressed,
                )
            )
        pos = body + length
        out.end = pos
        stream.seek(pos)
    every_channel = dict.fromkeys(out.channels, 0)  # a chunk may hold any of them
    for chunk in out.chunks:
        chunk.message_index_offsets = every_channel
    return out

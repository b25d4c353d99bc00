"""`McapLogger`: writes cufund messages to an MCAP file while a run goes, at about a microsecond per message.

``write`` only adds the message to its topic's accumulator: for fixed-size messages, its numbers and its arrays'
bytes appended to one ``bytearray`` (:class:`cufund.logs.cdr.FixedAccumulator`); for the others, the message.
When a topic holds ``block_messages`` messages (or about ``chunk_bytes`` of encoded data) the whole block is
encoded at once (numpy structured arrays for the CDR rows, their Message records and the message index) and
handed to a background thread that compresses it and writes it as one chunk. Memory stays bounded by one block
per topic (and at most 8 chunks waiting for the disk), however long the run. The summary (schemas, channels,
statistics, chunk and metadata indexes) is written by :meth:`close`.

The record layouts follow the MCAP specification (https://mcap.dev/spec); schemas, channels and the summary use
the ``mcap`` package's record classes. Each Message record's ``sequence`` is the logger's running write count
(mod 2**32), so :func:`cufund.logs.read_mcap` restores the exact order of messages that share a log time.
"""

from __future__ import annotations

import itertools
import os
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, DataEnd, Footer, Header, Metadata, MetadataIndex, Schema, Statistics,
                          SummaryOffset)

from .chunk_writer import ChunkWriter
from .codecs import Codec, codec_for, view_rows

__all__ = ["MAGIC", "McapLogger"]

MAGIC = b"\x89MCAP0\r\n"
_MESSAGE_HEADER = 2 + 4 + 8 + 8  # channel id, sequence, log time, publish time
_COMPRESSIONS = ("lz4", "zstd", "")


class _TopicBuffer:
    __slots__ = ("topic", "codec", "cls", "accumulator", "add", "channels", "limit", "count")

    def __init__(self, topic: str, codec: Codec, accumulator: Any, channels: list[int], limit: int):
        self.topic, self.codec, self.channels, self.limit = topic, codec, channels, limit
        self.cls, self.accumulator, self.add = codec.cls, accumulator, accumulator.add
        self.count = 0


class McapLogger:
    """Writes messages to ``path`` (an MCAP file Foxglove Studio and the ``mcap`` tools open without ROS).

    ``metadata`` (str -> str) is stored as an MCAP Metadata record named ``cufund``. ``compression``: ``lz4``
    (default: about twice as fast as zstd level 1 on these records, files about 40 % larger), ``zstd`` or ``""``.
    ``background``: compress and write on a thread (the default), or in the caller's. Use as a context manager or
    call :meth:`close`; a file whose logger was never closed has no summary (the ``mcap`` tools can recover its
    complete chunks)."""

    def __init__(self, path: str | os.PathLike[str], metadata: dict[str, str] | None = None, *,
                 block_messages: int = 1024, chunk_bytes: int = 1 << 20, compression: str = "lz4",
                 background: bool = True):
        if compression not in _COMPRESSIONS:
            raise ValueError(f"compression must be one of {_COMPRESSIONS}, got {compression!r}")
        if not (isinstance(block_messages, int) and block_messages >= 1):
            raise ValueError(f"block_messages must be a positive int, got {block_messages!r}")
        if not (isinstance(chunk_bytes, int) and chunk_bytes >= 1):
            raise ValueError(f"chunk_bytes must be a positive int, got {chunk_bytes!r}")
        if metadata is not None and not (isinstance(metadata, dict) and all(
                isinstance(k, str) and isinstance(v, str) for k, v in metadata.items())):
            raise TypeError("metadata must be a dict of str to str")
        self.path = Path(path)
        self._block = block_messages
        self._chunk_bytes = chunk_bytes
        self._compression = compression
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed by close()
        self._topics: dict[str, _TopicBuffer] = {}
        self._schemas: list[Schema] = []
        self._schema_ids: dict[tuple[str, str, bytes], int] = {}
        self._channels: list[Channel] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = {}
        self._sequence = itertools.count()
        self._start_time: int | None = None
        self._end_time = 0
        self._out = ChunkWriter(self._file, compression, background=False)
        self._file.write(MAGIC)
        self._record(Header(profile="", library="cufund"))
        if metadata:
            offset = self._file.tell()
            length = self._record(Metadata(name="cufund", metadata=dict(metadata)))
            self._metadata_indexes.append(MetadataIndex(offset=offset, length=length, name="cufund"))
        if background:
            self._out = ChunkWriter(self._file, compression, background=True)

    # -- the hot path -------------------------------------------------------------------------------------------
    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int) -> None:
        """Logs ``message`` on ``topic`` at ``log_time_ns`` (when it became visible) and ``publish_time_ns`` [ns].

        A topic's codec is chosen from its first message; a later message of another type raises TypeError here,
        a bad time or array shape when its block is encoded (at the latest at :meth:`close`). A fixed-size message
        is copied into the block's buffer at once: no reference to it or its arrays is kept."""
        buffer = self._topics.get(topic)
        if buffer is None:
            buffer = self._open_topic(topic, message)
        if message.__class__ is not buffer.cls:
            raise TypeError(f"topic {buffer.topic!r} is logged as {buffer.cls.__name__} (its first message), "
                            f"got a {type(message).__name__}")
        count = buffer.count = buffer.add(message, log_time_ns, publish_time_ns, next(self._sequence))
        if count >= buffer.limit:
            self._flush(buffer)

    # -- topics and chunks --------------------------------------------------------------------------------------
    def _open_topic(self, topic: str, message: Any) -> _TopicBuffer:
        if self._file.closed:
            raise ValueError(f"write to a closed McapLogger ({self.path})")
        if not isinstance(topic, str) or not topic.startswith("/"):
            raise ValueError(f"topic must be an absolute name like '/sensors/imu', got {topic!r}")
        codec = codec_for(topic, message)
        channels = [self._channel(str(topic), codec.schema_name, codec.schema_encoding, codec.schema_data,
                                  codec.message_encoding, codec.metadata())]
        for view in codec.views:
            channels.append(self._channel(f"{topic}{view.suffix}", view.schema_name, view.schema_encoding,
                                          view.schema_text.encode(), view.message_encoding,
                                          {"cufund.view_of": str(topic)}))
        if codec.fixed_size:
            size = codec.fixed_size * (1 + len(codec.views))
        else:
            size = sum(len(b) for b in codec.encode([message], topic))
        limit = max(1, min(self._block, self._chunk_bytes // max(size, 1)))
        buffer = self._topics[topic] = _TopicBuffer(str(topic), codec, codec.accumulator(message), channels, limit)
        return buffer

    def _channel(self, topic: str, schema_name: str, schema_encoding: str, schema_data: bytes,
                 message_encoding: str, metadata: dict[str, str]) -> int:
        key = (schema_name, schema_encoding, schema_data)
        schema_id = self._schema_ids.get(key)
        if schema_id is None:
            schema_id = self._schema_ids[key] = len(self._schemas) + 1
            schema = Schema(id=schema_id, data=schema_data, encoding=schema_encoding, name=schema_name)
            self._schemas.append(schema)
            self._record(schema)
        channel = Channel(id=len(self._channels) + 1, topic=topic, message_encoding=message_encoding,
                          metadata=metadata, schema_id=schema_id)
        self._channels.append(channel)
        self._counts[channel.id] = 0
        self._record(channel)
        return channel.id

    def _flush(self, buffer: _TopicBuffer) -> None:
        if not buffer.count:
            return
        buffer.count = 0
        codec, topic = buffer.codec, buffer.topic
        payload, log_times, publish_times, sequences = buffer.accumulator.drain(topic)
        log = _times(log_times, "log_time_ns", topic)
        publish = _times(publish_times, "publish_time_ns", topic)
        sequence = (np.asarray(sequences, dtype=np.uint64) & np.uint64(0xFFFFFFFF)).astype(np.uint32)
        groups = [(buffer.channels[0], payload)]
        if codec.views:
            groups += list(zip(buffer.channels[1:], view_rows(codec, payload)))
        self._write_chunk(groups, log, publish, sequence)

    def _write_chunk(self, groups: list[tuple[int, np.ndarray | list[bytes]]], log: np.ndarray,
                     publish: np.ndarray, sequence: np.ndarray) -> None:
        n = len(log)
        parts: list[bytes] = []
        indexes: list[tuple[int, bytes]] = []
        order = np.argsort(log, kind="stable")
        entries = np.empty(n, [("log", "<u8"), ("offset", "<u8")])
        entries["log"] = log[order]
        offset = 0
        for channel_id, payload in groups:
            records, offsets = _message_records(channel_id, payload, log, publish, sequence, offset)
            parts.append(records)
            offset += len(records)
            entries["offset"] = offsets[order]
            indexes.append((channel_id, entries.tobytes()))
            self._counts[channel_id] += n
        start, end = int(log.min()), int(log.max())
        self._out.chunk(b"".join(parts), start, end, indexes)
        self._start_time = start if self._start_time is None else min(self._start_time, start)
        self._end_time = max(self._end_time, end)

    # -- closing --------------------------------------------------------------------------------------------------
    def close(self) -> None:
        """Flushes every topic and writes the summary and footer; idempotent."""
        if self._file.closed:
            return
        topics, self._topics = self._topics, {}  # a later write finds no topic and raises in _open_topic
        try:
            for buffer in topics.values():
                self._flush(buffer)
            self._record(DataEnd(data_section_crc=0))
            self._out.close()
            self._write_summary()
        finally:
            self._out.close()
            self._file.close()

    def _write_summary(self) -> None:
        summary_start = self._file.tell()
        builder = RecordBuilder()
        offsets: list[SummaryOffset] = []
        statistics = Statistics(
            message_count=sum(self._counts.values()), schema_count=len(self._schemas),
            channel_count=len(self._channels), attachment_count=0, metadata_count=len(self._metadata_indexes),
            chunk_count=len(self._out.chunk_indexes), message_start_time=self._start_time or 0,
            message_end_time=self._end_time, channel_message_counts=dict(self._counts))
        groups = [(Opcode.SCHEMA, self._schemas), (Opcode.CHANNEL, self._channels), (Opcode.STATISTICS, [statistics]),
                  (Opcode.CHUNK_INDEX, self._out.chunk_indexes), (Opcode.METADATA_INDEX, self._metadata_indexes)]
        for opcode, records in groups:
            if not records:
                continue
            group_start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + group_start,
                                         group_length=builder.count - group_start))
        summary_offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start),
                         zlib.crc32(summary))
        self._file.write(summary)
        footer = RecordBuilder()
        Footer(summary_start=summary_start, summary_offset_start=summary_offset_start, summary_crc=crc).write(footer)
        self._file.write(footer.end() + MAGIC)

    def _record(self, record: Any) -> int:
        builder = RecordBuilder()
        record.write(builder)
        data = builder.end()
        self._out.write(data)
        return len(data)

    def __enter__(self) -> McapLogger:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        file = getattr(self, "_file", None)
        if file is not None and not file.closed:  # never closed: stop the writer thread, leave no summary
            try:
                self._out.close()
            finally:
                file.close()


def _times(values: Any, name: str, topic: str) -> np.ndarray:
    if isinstance(values, np.ndarray) and values.dtype == np.uint64:
        return values  # packed with struct "Q": already non-negative integers
    array = np.array(values)
    if array.dtype.kind not in "iu" or (array.size and array.min() < 0):
        raise TypeError(f"topic {topic!r}: {name} must be non-negative integer nanoseconds, got e.g. "
                        f"{values[0]!r}")
    return array.astype(np.uint64)


def _message_records(channel_id: int, payload: np.ndarray | list[bytes], log: np.ndarray, publish: np.ndarray,
                     sequence: np.ndarray, start: int) -> tuple[bytes, np.ndarray]:
    """The Message records of one channel's block and each record's offset in the chunk."""
    n = len(log)
    if isinstance(payload, np.ndarray):
        size = payload.shape[1]
        dtype = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"),
                          ("log", "<u8"), ("publish", "<u8"), ("data", "u1", (size,))])
        records = np.empty(n, dtype)
        records["op"] = Opcode.MESSAGE
        records["length"] = _MESSAGE_HEADER + size
        records["channel"] = channel_id
        records["sequence"] = sequence
        records["log"] = log
        records["publish"] = publish
        records["data"] = payload
        return records.tobytes(), start + np.arange(n, dtype=np.uint64) * dtype.itemsize
    parts, offsets, pos = [], np.empty(n, np.uint64), start
    for i, data in enumerate(payload):
        header = struct.pack("<BQHIQQ", Opcode.MESSAGE, _MESSAGE_HEADER + len(data), channel_id, int(sequence[i]),
                             int(log[i]), int(publish[i]))
        parts += [header, data]
        offsets[i] = pos
        pos += len(header) + len(data)
    return b"".join(parts), offsets

"""`McapLogger`: writes cufund messages to an MCAP file while a run goes, at well under a microsecond per message.

``write`` is a compiled builtin (:class:`cufund._core.logs.LogCore`): a fixed-size message (odometry, IMU,
setpoints, actuator commands) is copied field by field straight into a CDR row of its topic's block, with no
Python frame and no object kept. When a topic holds ``block_messages`` messages (or about ``chunk_bytes`` of
encoded data) the block goes to a C++ writer thread that builds the Message records (and the odometry's Foxglove
views), the message indexes, compresses (lz4 or zstd) and writes one chunk, never taking the GIL. Other messages
(JSON, point clouds, images) are kept by their topic in Python and encoded a block at a time. Memory stays
bounded by one block per topic (and at most 8 chunks waiting for the disk), however long the run. The summary
(schemas, channels, statistics, chunk and metadata indexes) is written by :meth:`close`.

The record layouts follow the MCAP specification (https://mcap.dev/spec); schemas, channels and the summary use
the ``mcap`` package's record classes. Each Message record's ``sequence`` is the logger's running write count
(mod 2**32), so :func:`cufund.logs.read_mcap` restores the exact order of messages that share a log time.
"""

from __future__ import annotations

import os
import struct
import weakref
import zlib
from pathlib import Path
from typing import Any

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from cufund._core.logs import LogCore

from .codecs import CdrCodec, Codec, codec_for

__all__ = ["MAGIC", "McapLogger"]

MAGIC = b"\x89MCAP0\r\n"
_COMPRESSIONS = ("lz4", "zstd", "")


class _Topic:
    """A topic's codec and channels; ``slot`` for a fixed-size topic packed in C++, else ``accumulator``."""

    __slots__ = ("topic", "codec", "cls", "channels", "limit", "slot", "accumulator", "count")

    def __init__(self, topic: str, codec: Codec, channels: list[int], limit: int):
        self.topic, self.codec, self.cls, self.channels, self.limit = topic, codec, codec.cls, channels, limit
        self.slot: int | None = None
        self.accumulator: Any = None
        self.count = 0


class McapLogger:
    """Writes messages to ``path`` (an MCAP file Foxglove Studio and the ``mcap`` tools open without ROS).

    ``metadata`` (str -> str) is stored as an MCAP Metadata record named ``cufund``. ``compression``: ``lz4``
    (default: about twice as fast as zstd level 1 on these records, files about 40 % larger), ``zstd`` or ``""``.
    ``background``: encode, compress and write on a C++ thread (the default), or in the caller's. Use as a
    context manager or call :meth:`close`; a file whose logger was never closed has no summary (the ``mcap``
    tools can recover its complete chunks)."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        metadata: dict[str, str] | None = None,
        *,
        block_messages: int = 1024,
        chunk_bytes: int = 1 << 20,
        compression: str = "lz4",
        background: bool = True,
    ):
        if compression not in _COMPRESSIONS:
            raise ValueError(f"compression must be one of {_COMPRESSIONS}, got {compression!r}")
        if not (isinstance(block_messages, int) and block_messages >= 1):
            raise ValueError(f"block_messages must be a positive int, got {block_messages!r}")
        if not (isinstance(chunk_bytes, int) and chunk_bytes >= 1):
            raise ValueError(f"chunk_bytes must be a positive int, got {chunk_bytes!r}")
        if metadata is not None and not (
            isinstance(metadata, dict) and all(isinstance(k, str) and isinstance(v, str) for k, v in metadata.items())
        ):
            raise TypeError("metadata must be a dict of str to str")
        self.path = Path(path)
        self._block = block_messages
        self._chunk_bytes = chunk_bytes
        self._compression = compression
        self._closed = False
        self._topics: dict[str, _Topic] = {}
        self._schemas: list[Schema] = []
        self._schema_ids: dict[tuple[str, str, bytes], int] = {}
        self._channels: list[Channel] = []
        self._metadata_indexes: list[MetadataIndex] = []
        fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o666)
        this = weakref.ref(self)  # the core must not keep its logger alive: an unclosed logger is freed at once

        def other(*args: Any) -> None:
            logger = this()
            if logger is None:
                raise ValueError("write to a McapLogger that no longer exists")
            logger._write_other(*args)

        self._core = LogCore(fd, compression, background, other)
        self.write = self._core.write  # type: ignore[method-assign]  # the instance's write: one C call per message
        head = MAGIC + self._record_bytes(Header(profile="", library="cufund"))
        self._core.write_records(head)
        if metadata:
            data = self._record_bytes(Metadata(name="cufund", metadata=dict(metadata)))
            self._metadata_indexes.append(MetadataIndex(offset=len(head), length=len(data), name="cufund"))
            self._core.write_records(data)

    # -- the hot path -------------------------------------------------------------------------------------------
    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int) -> None:
        """Logs ``message`` on ``topic`` at ``log_time_ns`` (when it became visible) and ``publish_time_ns`` [ns].

        A topic's codec is chosen from its first message; a later message of another type raises TypeError, a
        bad time (not a non-negative int) TypeError, an array of another shape ValueError naming the field. A
        fixed-size message is copied into its block at once: no reference to it or its arrays is kept. (Each
        instance replaces this method by its compiled ``LogCore.write``; this one documents it.)"""
        self._core.write(topic, message, log_time_ns, publish_time_ns)

    def _write_other(self, topic: str, message: Any, log_time_ns: Any, publish_time_ns: Any, sequence: int) -> None:
        """What ``LogCore.write`` does not pack itself: a new topic's first message, or a message of a topic
        encoded in Python."""
        if self._closed:
            raise ValueError(f"write to a closed McapLogger ({self.path})")
        entry = self._topics.get(topic)
        if entry is None:
            entry = self._open_topic(topic, message)
        if entry.slot is not None:
            self._core.add_with_sequence(entry.slot, message, log_time_ns, publish_time_ns, sequence)
            return
        if message.__class__ is not entry.cls:
            raise TypeError(_wrong_type(entry, message))
        log = _time(log_time_ns, "log_time_ns", entry.topic)
        publish = _time(publish_time_ns, "publish_time_ns", entry.topic)
        entry.count = entry.accumulator.add(message, log, publish, sequence)
        if entry.count >= entry.limit:
            self._flush(entry)

    # -- topics and chunks --------------------------------------------------------------------------------------
    def _open_topic(self, topic: str, message: Any) -> _Topic:
        if not isinstance(topic, str) or not topic.startswith("/"):
            raise ValueError(f"topic must be an absolute name like '/sensors/imu', got {topic!r}")
        codec = codec_for(topic, message)
        channels = [
            self._channel(
                str(topic),
                codec.schema_name,
                codec.schema_encoding,
                codec.schema_data,
                codec.message_encoding,
                codec.metadata(),
            )
        ]
        for view in codec.views:
            channels.append(
                self._channel(
                    view.topic(str(topic)),
                    view.schema_name,
                    view.schema_encoding,
                    view.schema_text.encode(),
                    view.message_encoding,
                    {} if view.absolute else {"cufund.view_of": str(topic)},
                    shared=view.absolute,
                )
            )
        for suffix, (schema_name, schema_text), schema_encoding, message_encoding, _ in codec.companions:
            channels.append(
                self._channel(
                    f"{topic}{suffix}",
                    schema_name,
                    schema_encoding,
                    schema_text.encode(),
                    message_encoding,
                    {"cufund.view_of": str(topic)},
                )
            )
        if codec.fixed_size:
            size = codec.fixed_size + sum(view.layout.size for view in codec.views)
        else:
            size = sum(len(b) for b in codec.encode([message], topic))
        limit = max(1, min(self._block, self._chunk_bytes // max(size, 1)))
        entry = self._topics[topic] = _Topic(str(topic), codec, channels, limit)
        if isinstance(codec, CdrCodec):
            entry.slot = self._add_fixed_topic(topic, entry, message)
        else:
            entry.accumulator = codec.accumulator()
        return entry

    def _add_fixed_topic(self, topic: str, entry: _Topic, first: Any) -> int:
        codec = entry.codec
        assert isinstance(codec, CdrCodec)
        layout, name = codec.layout, entry.topic
        template, scalars, arrays, absent = layout.row_spec(first)
        views = [
            (channel, *view.spec(layout.layout)) for channel, view in zip(entry.channels[1:], codec.views, strict=True)
        ]

        def slow(message: Any, log_time_ns: Any, publish_time_ns: Any) -> tuple[bytes, int, int]:
            if message.__class__ is not entry.cls:
                raise TypeError(_wrong_type(entry, message))
            return (
                layout.row(message, name),
                _time(log_time_ns, "log_time_ns", name),
                _time(publish_time_ns, "publish_time_ns", name),
            )

        return self._core.add_fixed_topic(
            topic, entry.cls, entry.channels[0], template, scalars, arrays, absent, views, entry.limit, slow
        )

    def _channel(
        self,
        topic: str,
        schema_name: str,
        schema_encoding: str,
        schema_data: bytes,
        message_encoding: str,
        metadata: dict[str, str],
        shared: bool = False,
    ) -> int:
        """A new channel's id; ``shared``: the channel of ``topic`` with this schema if there is one already (the
        ``/tf`` every odometry topic adds to, ``/tf_static``)."""
        if shared:
            for existing in self._channels:
                if existing.topic == topic and self._schemas[existing.schema_id - 1].name == schema_name:
                    return existing.id
        key = (schema_name, schema_encoding, schema_data)
        schema_id = self._schema_ids.get(key)
        if schema_id is None:
            schema_id = self._schema_ids[key] = len(self._schemas) + 1
            schema = Schema(id=schema_id, data=schema_data, encoding=schema_encoding, name=schema_name)
            self._schemas.append(schema)
            self._core.write_records(self._record_bytes(schema))
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            metadata=metadata,
            schema_id=schema_id,
        )
        self._channels.append(channel)
        self._core.write_records(self._record_bytes(channel))
        return channel.id

    def _flush(self, entry: _Topic) -> None:
        if entry.slot is not None:
            self._core.flush(entry.slot)
            return
        if not entry.count:
            return
        entry.count = 0
        messages = [item[0] for item in entry.accumulator.items] if entry.codec.companions else []
        payloads, log, publish, sequence = entry.accumulator.drain(entry.topic)
        self._core.write_payloads(entry.channels[0], payloads, log, publish, sequence)
        for channel, (*_, encode) in zip(entry.channels[1:], entry.codec.companions, strict=True):
            self._core.write_payloads(channel, [encode(m) for m in messages], log, publish, sequence)

    def write_encoded(
        self,
        topic: str,
        schema: tuple[str, str],
        data: bytes,
        log_time_ns: int,
        *,
        schema_encoding: str = "ros2msg",
        message_encoding: str = "cdr",
    ) -> None:
        """Writes one message already encoded (``data``) on ``topic`` with ``schema`` (name, definition): what no
        cufund message carries (``/tf_static``, the world's ``foxglove.SceneUpdate``). Not read back by
        :func:`cufund.logs.read_mcap` (its channel names no cufund codec)."""
        if self._closed:
            raise ValueError(f"write to a closed McapLogger ({self.path})")
        if not isinstance(topic, str) or not topic.startswith("/"):
            raise ValueError(f"topic must be an absolute name like '/tf_static', got {topic!r}")
        if not isinstance(data, bytes):
            raise TypeError(f"topic {topic!r}: data must be bytes, got {type(data).__name__}")
        log = _time(log_time_ns, "log_time_ns", topic)
        name, text = schema
        channel = self._channel(topic, name, schema_encoding, text.encode(), message_encoding, {}, shared=True)
        self._core.write_payloads(channel, [data], [log], [log], [0])

    def pending(self, topic: str) -> int:
        """Messages of ``topic`` held in memory, not yet handed to the writer (at most one block)."""
        entry = self._topics[topic]
        return self._core.pending(entry.slot) if entry.slot is not None else entry.count

    # -- closing --------------------------------------------------------------------------------------------------
    def close(self) -> None:
        """Flushes every topic and writes the summary and footer; idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            for entry in self._topics.values():
                self._flush(entry)
            self._core.write_records(self._record_bytes(DataEnd(data_section_crc=0)))
            self._core.finish()
            self._core.write_records(self._summary(self._core.position))
        finally:
            self._core.close()

    def _summary(self, summary_start: int) -> bytes:
        builder = RecordBuilder()
        offsets: list[SummaryOffset] = []
        counts = {c.id: 0 for c in self._channels}
        counts.update(self._core.message_counts())
        start, end = self._core.time_range() or (0, 0)
        chunk_indexes = [
            ChunkIndex(
                message_start_time=a,
                message_end_time=b,
                chunk_start_offset=offset,
                chunk_length=length,
                message_index_offsets=dict(indexes),
                message_index_length=index_length,
                compression=self._compression,
                compressed_size=compressed,
                uncompressed_size=uncompressed,
            )
            for a, b, offset, length, indexes, index_length, compressed, uncompressed in self._core.chunks()
        ]
        statistics = Statistics(
            message_count=sum(counts.values()),
            schema_count=len(self._schemas),
            channel_count=len(self._channels),
            attachment_count=0,
            metadata_count=len(self._metadata_indexes),
            chunk_count=len(chunk_indexes),
            message_start_time=start,
            message_end_time=end,
            channel_message_counts=counts,
        )
        groups: list[tuple[Opcode, Any]] = [
            (Opcode.SCHEMA, self._schemas),
            (Opcode.CHANNEL, self._channels),
            (Opcode.STATISTICS, [statistics]),
            (Opcode.CHUNK_INDEX, chunk_indexes),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        ]
        for opcode, records in groups:
            if not records:
                continue
            group_start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(
                SummaryOffset(
                    group_opcode=opcode,
                    group_start=summary_start + group_start,
                    group_length=builder.count - group_start,
                )
            )
        summary_offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        crc = zlib.crc32(
            struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start), zlib.crc32(summary)
        )
        footer = RecordBuilder()
        Footer(summary_start=summary_start, summary_offset_start=summary_offset_start, summary_crc=crc).write(footer)
        return summary + footer.end() + MAGIC

    @staticmethod
    def _record_bytes(record: Any) -> bytes:
        builder = RecordBuilder()
        record.write(builder)
        return builder.end()

    def __enter__(self) -> McapLogger:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _wrong_type(entry: _Topic, message: Any) -> str:
    return (
        f"topic {entry.topic!r} is logged as {entry.cls.__name__} (its first message), got a {type(message).__name__}"
    )


def _time(value: Any, name: str, topic: str) -> int:
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and 0 <= value < 2**64:
        return int(value)
    raise TypeError(f"topic {topic!r}: {name} must be non-negative integer nanoseconds, got {value!r}")

"""`read_mcap`: the cufund messages of a log written by :class:`cufund.logs.McapLogger`, exactly as written.

The official ``mcap`` reader checks the file and reads its summary; the chunks are then merged in log-time order
by :mod:`cufund.logs.chunk_reader` (CRCs checked), ties in the order they were written. Each channel's metadata
names its codec and message class, which rebuild the same frozen dataclasses (float64 bit for bit, array dtypes
and shapes, enums as enums). Foxglove view channels
(``<topic>/pose``, ``<topic>/tf``) are derived data and are not returned.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader

from .chunk_reader import iter_chunk_messages
from .codecs import Codec, codec_from_channel

__all__ = ["LogRecord", "McapReadError", "log_metadata", "log_topics", "read_mcap"]


class LogRecord(NamedTuple):
    """One logged message."""

    topic: str
    log_time_ns: int
    """When the message became visible on the bus [ns of simulated time]."""
    publish_time_ns: int
    """When its publisher published it [ns]."""
    message: Any


class McapReadError(ValueError):
    """The file is not a complete, intact MCAP log (truncated, corrupt, or not MCAP)."""


_ERRORS = (McapError, OSError, EOFError, ValueError, KeyError, IndexError, UnicodeDecodeError, struct.error,
           zstandard.ZstdError, RuntimeError)  # lz4 reports corrupt frames as RuntimeError


def _open(path: Path) -> tuple[Any, Any, dict[int, tuple[str, Codec]]]:
    try:
        stream = open(path, "rb")  # noqa: SIM115 - the generator closes it
    except OSError as exc:
        raise McapReadError(f"cannot open log {str(path)!r}: {exc}") from exc
    try:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
    except _ERRORS as exc:
        stream.close()
        raise McapReadError(f"{str(path)!r} is not a complete MCAP log (truncated or corrupt?): {exc}") from exc
    if summary is None:
        stream.close()
        raise McapReadError(f"{str(path)!r} has no summary section: the logger that wrote it was not closed")
    codecs = {}
    try:
        for channel in summary.channels.values():
            if "cufund.codec" in channel.metadata:
                codecs[channel.id] = (channel.topic, codec_from_channel(channel.metadata))
    except ValueError as exc:
        stream.close()
        raise McapReadError(f"{str(path)!r}: {exc}") from exc
    return stream, reader, codecs


def log_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """The topics of a cufund log with the name of each one's message class."""
    stream, _, codecs = _open(Path(path))
    stream.close()
    return {topic: codec.cls.__name__ for topic, codec in codecs.values()}


def log_metadata(path: str | os.PathLike[str]) -> dict[str, str]:
    """The ``cufund`` metadata record of a log (what :class:`McapLogger` was given), or {}."""
    stream, reader, _ = _open(Path(path))
    try:
        for record in reader.iter_metadata():
            if record.name == "cufund":
                return dict(record.metadata)
    except _ERRORS as exc:
        raise McapReadError(f"{str(path)!r} is corrupt: {exc}") from exc
    finally:
        stream.close()
    return {}


def read_mcap(path: str | os.PathLike[str], topics: Iterable[str] | str | None = None) -> Iterator[LogRecord]:
    """The messages of the log at ``path`` (only ``topics`` when given), in log-time order.

    Raises :class:`McapReadError` at once when the file is missing, truncated or not a cufund MCAP log, and
    ``ValueError`` naming the topics a log has when a requested topic is not in it; a chunk found corrupt while
    iterating raises :class:`McapReadError` then."""
    path = Path(path)
    stream, reader, codecs = _open(path)
    if topics is not None:
        wanted = {str(topics)} if isinstance(topics, str) else {str(t) for t in topics}
        present = {topic for topic, _ in codecs.values()}
        missing = wanted - present
        if missing:
            stream.close()
            raise ValueError(f"topics {sorted(missing)} are not in {str(path)!r}; it has {sorted(present)}")
        codecs = {cid: tc for cid, tc in codecs.items() if tc[0] in wanted}
    return _iterate(path, stream, reader, codecs)


def _iterate(path: Path, stream: Any, reader: Any, codecs: dict[int, tuple[str, Codec]]) -> Iterator[LogRecord]:
    try:
        if not codecs:
            return
        summary = reader.get_summary()
        if not summary.chunk_indexes and summary.statistics and summary.statistics.message_count:
            raise McapReadError(f"{str(path)!r} has no chunk index (not written by cufund.logs.McapLogger)")
        try:
            for log, _, _, _, channel, publish, data in iter_chunk_messages(stream, summary.chunk_indexes,
                                                                              set(codecs)):
                topic, codec = codecs[channel]
                yield LogRecord(topic, log, publish, codec.decode(data))
        except _ERRORS as exc:
            raise McapReadError(f"{str(path)!r} is corrupt: {exc}") from exc
    finally:
        stream.close()

"""`read_mcap`: the cufund messages of a log written by :class:`cufund.logs.McapLogger`, exactly as written.

The official ``mcap`` reader checks the file and reads its summary; the chunks are then merged in log-time order
by :mod:`cufund.logs.chunk_reader` (CRCs checked), ties in the order they were written. Each channel's metadata
names its codec and message class, which rebuild the same frozen dataclasses (float64 bit for bit, array dtypes
and shapes, enums as enums); only allowed classes are used (:mod:`cufund.logs.message_classes`: a log never
imports or calls what it names). Channels that name no cufund codec (the standard views ``<topic>/ros``,
``<topic>/pose``, ``/tf``, ``/tf_static``, ``/clock``, scenes and paths) are derived data and are not returned.

A log whose run was killed has no summary: its records are then scanned from the start
(:mod:`cufund.logs.truncated`) and read up to the last complete one, with one :class:`TruncatedLogWarning`.
"""

from __future__ import annotations

import io
import os
import struct
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import zstandard
from mcap.exceptions import McapError
from mcap.reader import make_reader

from .chunk_reader import iter_chunk_messages
from .codecs import Codec, codec_from_channel
from .truncated import MAGIC, Recovered, scan_records

__all__ = ["LogRecord", "McapReadError", "TruncatedLogWarning", "log_metadata", "log_topics", "read_mcap"]


class LogRecord(NamedTuple):
    """One logged message."""

    topic: str
    log_time_ns: int
    """When the message became visible on the bus [ns of simulated time]."""
    publish_time_ns: int
    """When its publisher published it [ns]."""
    message: Any


class McapReadError(ValueError):
    """The file is not an intact MCAP log (corrupt, not MCAP, cut before its first records) or a channel names a
    class or codec cufund does not allow."""


class TruncatedLogWarning(UserWarning):
    """The log has no summary (its run was killed): it is read up to its last complete record."""


_ERRORS = (
    McapError,
    OSError,
    EOFError,
    ValueError,
    KeyError,
    IndexError,
    UnicodeDecodeError,
    struct.error,
    zstandard.ZstdError,
    RuntimeError,
    TypeError,
    AttributeError,
    OverflowError,
    RecursionError,
    MemoryError,
)  # lz4 reports corrupt frames as RuntimeError; TypeError: a message without its fields

_warned: set[tuple[str, int, int]] = set()


def _warn_truncated(path: Path, stream: Any, recovered: Recovered) -> None:
    """One line per truncated file per process (a LogPlayer opens its log more than once)."""
    st = os.fstat(stream.fileno())
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key in _warned:
        return
    _warned.add(key)
    warnings.warn(
        TruncatedLogWarning(
            f"{path} is truncated (no summary: was its run killed?): reading its {len(recovered.chunks)} complete "
            f"chunks, up to byte {recovered.end} of {st.st_size}"
        ),
        stacklevel=4,
    )


def _summary_of(path: Path, stream: Any) -> tuple[Any, Any]:
    """(channels by id, chunk indexes) from the summary, or from a scan of a log without one."""
    error: BaseException | None = None
    try:
        summary = make_reader(stream, validate_crcs=True).get_summary()
    except _ERRORS as exc:
        summary, error = None, exc
    if summary is not None:
        if not summary.chunk_indexes and summary.statistics and summary.statistics.message_count:
            raise McapReadError(f"{str(path)!r} has no chunk index (not written by cufund.logs.McapLogger)")
        return summary.channels, summary.chunk_indexes
    stream.seek(0)
    if stream.read(len(MAGIC)) != MAGIC:
        raise McapReadError(f"{str(path)!r} is not a complete MCAP log (not MCAP at all): {error or 'no summary'}")
    try:
        recovered = scan_records(stream)
    except _ERRORS as exc:
        raise McapReadError(f"{str(path)!r} is not a complete MCAP log and cannot be scanned: {exc}") from exc
    _warn_truncated(path, stream, recovered)
    return recovered.channels, recovered.chunks


def _open(path: Path) -> tuple[Any, list[Any], dict[int, tuple[str, Codec]]]:
    try:
        stream = open(path, "rb")
    except OSError as exc:
        raise McapReadError(f"cannot open log {str(path)!r}: {exc}") from exc
    try:
        channels, chunks = _summary_of(path, stream)
        codecs = {}
        for channel in channels.values():
            if "cufund.codec" in channel.metadata:
                where = f"{str(path)!r}: channel {channel.topic[:200]!r} (id {channel.id})"
                codecs[channel.id] = (channel.topic, codec_from_channel(channel.metadata, where))
    except McapReadError:
        stream.close()
        raise
    except ValueError as exc:
        stream.close()
        raise McapReadError(str(exc)) from exc
    except BaseException:
        stream.close()
        raise
    return stream, chunks, codecs


def log_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """The topics of a cufund log with the name of each one's message class."""
    stream, _, codecs = _open(Path(path))
    stream.close()
    return {topic: codec.cls.__name__ for topic, codec in codecs.values()}


def log_metadata(path: str | os.PathLike[str]) -> dict[str, str]:
    """The ``cufund`` metadata record of a log (what :class:`McapLogger` was given; it follows the header), or
    {}."""
    from mcap.data_stream import ReadDataStream
    from mcap.records import Metadata

    stream, _, _ = _open(Path(path))
    try:
        stream.seek(len(MAGIC))
        for _ in range(2):  # the header, then (when given) the cufund metadata
            head = stream.read(9)
            if len(head) < 9:
                return {}
            opcode, length = struct.unpack("<BQ", head)
            if opcode == 0x0C and length <= 64 << 20:
                body = stream.read(length)
                record = Metadata.read(ReadDataStream(io.BytesIO(body)))
                if record.name == "cufund":
                    return {str(k): str(v) for k, v in record.metadata.items()}
                return {}
            if opcode != 0x01:
                return {}
            stream.seek(length, 1)
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
    stream, chunks, codecs = _open(path)
    if topics is not None:
        wanted = {str(topics)} if isinstance(topics, str) else {str(t) for t in topics}
        present = {topic for topic, _ in codecs.values()}
        missing = wanted - present
        if missing:
            stream.close()
            raise ValueError(f"topics {sorted(missing)} are not in {str(path)!r}; it has {sorted(present)}")
        codecs = {cid: tc for cid, tc in codecs.items() if tc[0] in wanted}
    return _iterate(path, stream, chunks, codecs)


def _iterate(path: Path, stream: Any, chunks: list[Any], codecs: dict[int, tuple[str, Codec]]) -> Iterator[LogRecord]:
    try:
        if not codecs:
            return
        try:
            for log, _, _, _, channel, publish, data in iter_chunk_messages(stream, chunks, set(codecs)):
                topic, codec = codecs[channel]
                try:
                    message = codec.decode(data)
                except _ERRORS as exc:
                    text = str(exc)[:1000]
                    text = text if codec.where in text else f"{codec.where}: {text}"
                    raise McapReadError(f"{text} (the message at log time {log} ns)") from None
                yield LogRecord(topic, log, publish, message)
        except McapReadError:
            raise
        except _ERRORS as exc:
            raise McapReadError(f"{str(path)!r} is corrupt: {exc}") from exc
    finally:
        stream.close()

"""
The run log's hot path: packing messages into MCAP blocks (issue 10).
"""
from __future__ import annotations
import collections.abc
import typing
__all__: list[str] = ['LogCore']
class LogCore:
    """
    The hot path of cufund.logs.McapLogger: fixed-size messages packed into CDR rows per topic, blocks encoded, compressed and written by a C++ thread. Owns the file descriptor `fd`.
    """
    def __init__(self, fd: typing.SupportsInt | typing.SupportsIndex, compression: str, background: bool, other: typing.Any) -> None:
        ...
    def add_fixed_topic(self, topic: typing.Any, cls: typing.Any, channel: typing.SupportsInt | typing.SupportsIndex, row_template: bytes, scalars: collections.abc.Sequence[tuple[str, str, typing.SupportsInt | typing.SupportsIndex]], arrays: collections.abc.Sequence[tuple[str, typing.Any, typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex]], absent: collections.abc.Sequence[str], views: collections.abc.Sequence[tuple[typing.SupportsInt | typing.SupportsIndex, bytes, collections.abc.Sequence[tuple[typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex]], collections.abc.Sequence[tuple[typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex]], collections.abc.Sequence[tuple[typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex, typing.SupportsInt | typing.SupportsIndex]]]], limit: typing.SupportsInt | typing.SupportsIndex, slow: typing.Any) -> int:
        """
        Registers a topic of fixed-size messages (scalars: (attr, 'd'|'q'|'?', offset); arrays: (attr, dtype, nbytes, offset); absent: attrs that must be None; views: (channel, template, copies (dst, src, bytes), stamps (sec, nsec, src t), rotations (dst, src v, src q [w, x, y, z]): dst = R(q)^T v); slow(message, log, publish) -> (row, log, publish)); its slot.
        """
    def add_with_sequence(self, slot: typing.SupportsInt | typing.SupportsIndex, message: typing.Any, log: typing.Any, publish: typing.Any, sequence: typing.SupportsInt | typing.SupportsIndex) -> None:
        ...
    def chunks(self) -> list:
        """
        (start, end, chunk_start, chunk_length, message index offsets, message index length, compressed size, uncompressed size) of every chunk written.
        """
    def close(self) -> None:
        """
        Finishes and closes the file.
        """
    def finish(self) -> None:
        """
        Waits until everything submitted is in the file.
        """
    def flush(self, slot: typing.SupportsInt | typing.SupportsIndex) -> None:
        """
        Hands a fixed topic's partial block to the writer.
        """
    def message_counts(self) -> dict:
        """
        Messages written per channel.
        """
    def pending(self, slot: typing.SupportsInt | typing.SupportsIndex) -> int:
        """
        Messages of a fixed topic not yet handed over.
        """
    def time_range(self) -> typing.Any:
        """
        (first, last) log time written [ns], or None.
        """
    def write_payloads(self, channel: typing.SupportsInt | typing.SupportsIndex, payloads: collections.abc.Sequence[bytes], log: collections.abc.Sequence[typing.SupportsInt | typing.SupportsIndex], publish: collections.abc.Sequence[typing.SupportsInt | typing.SupportsIndex], sequence: collections.abc.Sequence[typing.SupportsInt | typing.SupportsIndex]) -> None:
        """
        One chunk of already encoded messages of one channel.
        """
    def write_records(self, records: bytes) -> None:
        """
        Raw records, after what was submitted.
        """
    @property
    def position(self) -> int:
        """
        The file position (after finish).
        """
    @property
    def write(self) -> typing.Any:
        """
        write(topic, message, log_time_ns, publish_time_ns) as a plain builtin.
        """

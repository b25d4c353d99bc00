"""
The run log's hot path: packing messages into MCAP blocks (issue 10).
"""
from __future__ import annotations
import collections.abc
import typing
__all__: list[str] = ['RecordPacker']
class RecordPacker:
    """
    Appends messages of one fixed layout to a byte buffer of packed records: log, publish and sequence (uint64), the scalars, then the arrays' bytes (little-endian host).
    """
    def __init__(self, scalar_names: collections.abc.Sequence[str], scalar_codes: str, array_names: collections.abc.Sequence[str], array_dtypes: collections.abc.Sequence[typing.Any], array_nbytes: collections.abc.Sequence[typing.SupportsInt | typing.SupportsIndex], absent_names: collections.abc.Sequence[str], slow: typing.Any) -> None:
        ...
    def add(self, message: typing.Any, log: typing.Any, publish: typing.Any, sequence: typing.Any) -> int:
        """
        Packs the message, or calls slow(index, log, publish, sequence, message) when it does not fit the layout; returns the messages added since the last drain.
        """
    def drain(self) -> tuple:
        """
        (bytes of the packed records, their number); empties the buffer.
        """
    @property
    def count(self) -> int:
        ...
    @property
    def fast_add(self) -> typing.Any:
        """
        add as a plain builtin (no pybind11 dispatch): what the logger calls per message.
        """
    @property
    def record_bytes(self) -> int:
        ...

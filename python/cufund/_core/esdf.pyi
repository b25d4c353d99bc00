"""
Occupancy mapping and exact Euclidean distance fields (paper §2.3).
"""
from __future__ import annotations
import collections.abc
import numpy
import numpy.typing
import typing
__all__: list[str] = ['EsdfMap', 'edt']
class EsdfMap:
    """
    Occupancy grid with an incrementally exact ESDF; use cufund.mapping.EsdfMap.
    """
    @typing.overload
    def __init__(self, origin_W: typing.Any, shape: typing.Any, resolution: typing.SupportsFloat | typing.SupportsIndex, log_odds_hit: typing.SupportsFloat | typing.SupportsIndex, log_odds_miss: typing.SupportsFloat | typing.SupportsIndex, log_odds_min: typing.SupportsFloat | typing.SupportsIndex, log_odds_max: typing.SupportsFloat | typing.SupportsIndex, log_odds_occupied: typing.SupportsFloat | typing.SupportsIndex, max_range: typing.SupportsFloat | typing.SupportsIndex, signed: bool, nthreads: typing.SupportsInt | typing.SupportsIndex, merge_beams: bool = False) -> None:
        ...
    @typing.overload
    def __init__(self, other: EsdfMap) -> None:
        """
        A deep copy.
        """
    def distances(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        ...
    def insert_frames(self, frames: collections.abc.Sequence, knots_t: typing.Any, knots_p: typing.Any, knots_q: typing.Any, R_BL: typing.Any, t_BL: typing.Any) -> dict:
        ...
    def insert_scan(self, points_W: typing.Any, origin_W: typing.Any) -> dict:
        ...
    def insert_scans(self, scans: collections.abc.Sequence) -> dict:
        ...
    def inside_squared(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        ...
    def log_odds(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        ...
    def occupied(self) -> numpy.typing.NDArray[numpy.bool]:
        ...
    def outside_squared(self) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
        ...
    def query(self, points_W: typing.Any, gradient: bool) -> typing.Any:
        ...
    def recompute(self) -> None:
        ...
    def set_log_odds(self, log_odds: typing.Any) -> dict:
        """
        Sets every voxel's log-odds (a saved log_odds()) and updates the field.
        """
    def set_occupied(self, index: typing.Annotated[numpy.typing.ArrayLike, numpy.int64], value: typing.Annotated[numpy.typing.ArrayLike, numpy.uint8]) -> dict:
        ...
def edt(occupied: typing.Any, voxel_size: typing.Any, signed: bool, nthreads: typing.SupportsInt | typing.SupportsIndex, single: bool) -> numpy.ndarray[typing.Any, numpy.dtype[typing.Any]]:
    """
    Exact Euclidean distance transform; use cufund.mapping.edt, which documents the arguments.
    """

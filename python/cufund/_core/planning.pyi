"""
Clearance queries and grid path search on the ESDF (paper §2.3).
"""
from __future__ import annotations
import cufund._core.esdf
import numpy
import numpy.typing
import typing
__all__: list[str] = ['ClearanceQuery', 'GridAStar', 'min_derivative_spline', 'optimize_bspline', 'optimize_segment_times', 'snap_cost_and_gradient', 'voxelize_triangles']
class ClearanceQuery:
    """
    Certified clearance on an ESDF map; use cufund.planning.ClearanceQuery.
    """
    @typing.overload
    def __init__(self, esdf_map: cufund._core.esdf.EsdfMap) -> None:
        ...
    @typing.overload
    def __init__(self, origin_W: typing.Any, resolution: typing.SupportsFloat | typing.SupportsIndex, distances: typing.Any) -> None:
        ...
    def clearance(self, x: typing.SupportsFloat | typing.SupportsIndex, y: typing.SupportsFloat | typing.SupportsIndex, z: typing.SupportsFloat | typing.SupportsIndex) -> float:
        ...
    def clearance_many(self, points_W: typing.Any) -> numpy.typing.NDArray[numpy.float64]:
        ...
    def scalar_functions(self) -> tuple[typing.Any, typing.Any]:
        """
        (clearance(x, y, z), segment_free(x0, y0, z0, x1, y1, z1, radius)) as plain builtins that skip pybind11's dispatch (each keeps this query alive)
        """
    def segment_free(self, x0: typing.SupportsFloat | typing.SupportsIndex, y0: typing.SupportsFloat | typing.SupportsIndex, z0: typing.SupportsFloat | typing.SupportsIndex, x1: typing.SupportsFloat | typing.SupportsIndex, y1: typing.SupportsFloat | typing.SupportsIndex, z1: typing.SupportsFloat | typing.SupportsIndex, radius: typing.SupportsFloat | typing.SupportsIndex) -> bool:
        ...
    def segments_free(self, path_W: typing.Any, radius: typing.SupportsFloat | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.bool]:
        ...
    def shortcut(self, path_W: typing.Any, radius: typing.SupportsFloat | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.float64]:
        ...
    @property
    def min_step(self) -> float:
        ...
class GridAStar:
    """
    Deterministic A* on the ESDF grid; use cufund.planning.GridPathSearch.
    """
    def __init__(self) -> None:
        ...
    def plan(self, query: ClearanceQuery, start_W: typing.Any, goal_W: typing.Any, radius: typing.SupportsFloat | typing.SupportsIndex, max_expansions: typing.SupportsInt | typing.SupportsIndex, shortcut: bool, heuristic_weight: typing.SupportsFloat | typing.SupportsIndex, z_min: typing.SupportsFloat | typing.SupportsIndex = ..., z_max: typing.SupportsFloat | typing.SupportsIndex = ...) -> dict:
        ...
def min_derivative_spline(values: typing.Any, durations: typing.Any, order: typing.SupportsInt | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.float64]:
    """
    Coefficients (M, 2 order, d) of the minimum-derivative spline through values (M + 1, d) with durations (M,).
    """
def optimize_bspline(esdf_map: cufund._core.esdf.EsdfMap, start: typing.Any, initial: typing.Any, tail: typing.Any, end_target: typing.Any, pull_end: bool, w_smooth: typing.SupportsFloat | typing.SupportsIndex, w_collision: typing.SupportsFloat | typing.SupportsIndex, w_feasibility: typing.SupportsFloat | typing.SupportsIndex, w_end: typing.SupportsFloat | typing.SupportsIndex, d_safe: typing.SupportsFloat | typing.SupportsIndex, v_max: typing.SupportsFloat | typing.SupportsIndex, a_max: typing.SupportsFloat | typing.SupportsIndex, dt: typing.SupportsFloat | typing.SupportsIndex, max_iterations: typing.SupportsInt | typing.SupportsIndex) -> dict:
    ...
def optimize_segment_times(values: typing.Any, durations: typing.Any, max_iterations: typing.SupportsInt | typing.SupportsIndex, gtol: typing.SupportsFloat | typing.SupportsIndex) -> dict:
    """
    Snap-optimal segment times with the same total (BFGS on log T); a dict of durations, iterations, evaluations.
    """
def snap_cost_and_gradient(values: typing.Any, durations: typing.Any) -> tuple[float, numpy.typing.NDArray[numpy.float64]]:
    """
    (snap cost J, dJ/dT (M,)) of the minimum-snap spline.
    """
def voxelize_triangles(origin_W: typing.Any, shape: typing.Any, resolution: typing.SupportsFloat | typing.SupportsIndex, vertices: typing.Any, triangles: typing.Any) -> numpy.typing.NDArray[numpy.int64]:
    ...

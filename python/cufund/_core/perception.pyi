"""
The tunnel detector's kernels: DBSCAN, line support, deskew-crop.
"""
from __future__ import annotations
import numpy
import numpy.typing
import typing
__all__: list[str] = ['dbscan', 'deskew_crop', 'line_support']
def dbscan(points: typing.Any, eps: typing.Any, min_points: typing.Any) -> numpy.typing.NDArray[numpy.int64]:
    """
    DBSCAN cluster labels (N,) int64 of ``points`` (N, 3), as Open3D's PointCloud.cluster_dbscan(eps,
    min_points) labels them: core points have >= min_points points (themselves included) closer than eps [m];
    clusters numbered 0, 1, ... by their lowest-index core point; a border point takes the lowest-numbered
    cluster near it; noise is -1.
    """
def deskew_crop(points_L: typing.Any, dt: typing.Any, stride: typing.Any, span: typing.Any, p_WL: typing.Any, R_WL: typing.Any, max_range: typing.Any, z_min: typing.Any, z_max: typing.Any, tall_z: typing.Any, column_cell: typing.Any, tall: typing.Any) -> tuple[numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.int64]]:
    """
    A scan moved to the world point by point and cropped (the tunnel detector's input). Rows 0, stride, ...
    of ``points_L`` (N, 3) [m] fired at ``dt`` (N,) [s] from the scan start; K + 1 sensor poses ``p_WL``
    (K + 1, 3) [m], ``R_WL`` (K + 1, 3, 3) evenly over [0, span] [s]: a point is moved with the two poses
    around its time and the results blended linearly. Keeps the points 1e-6 m to max_range [m] from the
    sensor with z in [z_min, z_max] [m], in order, except those in tall x-y columns (keys as
    detection.column_keys, edge column_cell [m]): the sorted int64 keys ``tall``, and the columns where a kept
    point of this scan lies above tall_z [m]. Returns (points_W (M, 3), unit rays_W (M, 3) from the sensor,
    new_tall: the sorted keys of those new tall columns not in ``tall``).
    """
def line_support(along: typing.Any, inlier: typing.Any) -> tuple[numpy.typing.NDArray[numpy.int64], numpy.typing.NDArray[numpy.int64]]:
    """
    Support of K candidate lines over N points: ``along`` (N, K) integer bin of each point along each line,
    ``inlier`` (N, K) bool. Returns (covered (K,), counts (K,)) int64: the distinct bins among each line's
    inliers, and its inliers.
    """

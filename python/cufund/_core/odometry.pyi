"""
LiDAR-inertial odometry kernels (issue 12).
"""
from __future__ import annotations
import numpy
import numpy.typing
import typing
__all__: list[str] = ['VoxelMap', 'deskew', 'imu_propagate', 'plane_terms', 'prepare_scan', 'voxel_downsample']
class VoxelMap:
    """
    Incremental hashed voxel map with point-to-plane registration terms.
    """
    def __init__(self, voxel_size: typing.SupportsFloat | typing.SupportsIndex = 0.5, max_points_per_voxel: typing.SupportsInt | typing.SupportsIndex = 20, min_point_distance: typing.SupportsFloat | typing.SupportsIndex = 0.02, max_distance: typing.SupportsFloat | typing.SupportsIndex = 100.0, max_voxels: typing.SupportsInt | typing.SupportsIndex = 1000000) -> None:
        ...
    def __len__(self) -> int:
        ...
    def clear(self) -> None:
        ...
    def evict(self, origin: typing.Any) -> None:
        ...
    def fit_planes(self, points_I: typing.Any, R_WI: typing.Any, p_W: typing.Any, neighbours: typing.SupportsInt | typing.SupportsIndex = 5, max_neighbour_distance: typing.SupportsFloat | typing.SupportsIndex = 1.0, max_plane_rms: typing.SupportsFloat | typing.SupportsIndex = 0.05, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> tuple[numpy.typing.NDArray[numpy.bool], numpy.typing.NDArray[numpy.float64]]:
        """
        Fits a plane to the `neighbours` nearest map points of each of points_I (N, 3) placed by (R_WI, p_W): (valid (N,), planes (N, 4) [unit normal, offset], normal . x + offset = 0 in the world).
        """
    def insert(self, points_W: typing.Any, origin: typing.Any) -> int:
        """
        Adds world points (N, 3) [m], then evicts voxels far from origin (3,). Returns how many were kept.
        """
    def knn(self, queries: typing.Any, k: typing.SupportsInt | typing.SupportsIndex, max_distance: typing.SupportsFloat | typing.SupportsIndex, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> tuple[numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.float64]]:
        """
        The k nearest stored points within max_distance [m] (capped at the voxel size) of each query (Q, 3): (neighbours (Q, k, 3), squared distances (Q, k)) ascending; NaN / inf where fewer were found.
        """
    def point_to_plane(self, points_I: typing.Any, R_WI: typing.Any, p_W: typing.Any, neighbours: typing.SupportsInt | typing.SupportsIndex = 5, max_neighbour_distance: typing.SupportsFloat | typing.SupportsIndex = 1.0, max_plane_rms: typing.SupportsFloat | typing.SupportsIndex = 0.05, max_residual: typing.SupportsFloat | typing.SupportsIndex = 0.5, robust: str = 'huber', robust_scale: typing.SupportsFloat | typing.SupportsIndex = 0.05, sigma: typing.SupportsFloat | typing.SupportsIndex = 0.02, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> dict:
        """
        Point-to-plane terms of points_I (N, 3) seen from the pose (R_WI (3, 3), p_W (3,)): a plane is fitted to each point's `neighbours` nearest map points. Returns a dict: valid (N,), residual (N,) [m], normal (N, 3), weight (N,) (robust 'none' | 'huber' | 'cauchy' at robust_scale [m]), H (6, 6) and b (6,) (sums of w J^T J / sigma^2 and w J^T r / sigma^2 for the right perturbation T_WI Exp(xi), xi = [rotation, translation]), cost, inliers.
        """
    def points(self) -> numpy.typing.NDArray[numpy.float64]:
        """
        Every stored point (M, 3) [m].
        """
    @property
    def voxel_count(self) -> int:
        ...
    @property
    def voxel_size(self) -> float:
        ...
def deskew(points_L: typing.Any, t_points: typing.Any, knot_t: typing.Any, states: typing.Any, rates: typing.Any, t_ref: typing.SupportsFloat | typing.SupportsIndex, T_BI: typing.Any, T_BL: typing.Any, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> numpy.typing.NDArray[numpy.float64]:
    """
    Moves each point of points_L (N, 3), fired at t_points (N,) [s], to the LiDAR frame at t_ref along the IMU trajectory (knot_t (K,), states (K, 10), rates (K-1, 6) as imu_propagate returns them); T_BI and T_BL are the 4x4 IMU->body and LiDAR->body extrinsics. Returns (N, 3) float64.
    """
def imu_propagate(p_W: typing.Any, v_W: typing.Any, q_WI: typing.Any, bias_acc: typing.Any, bias_gyr: typing.Any, gravity_W: typing.Any, dt: typing.Any, acc: typing.Any, gyr: typing.Any) -> tuple[numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.float64]]:
    """
    Propagates an IMU-frame state through samples held over dt (n,) [s] with accelerometer acc (n, 3) [m/s^2] and gyroscope gyr (n, 3) [rad/s] readings, exactly as GTSAM's tangent-space preintegration. Returns (states (n+1, 10) [p_W, v_W, q_WI (w, x, y, z)], rates (n, 6) [a_W, w_I] held over each sample).
    """
def plane_terms(points_I: typing.Any, planes: typing.Any, valid: typing.Any, R_WI: typing.Any, p_W: typing.Any, max_residual: typing.SupportsFloat | typing.SupportsIndex = 0.5, robust: str = 'huber', robust_scale: typing.SupportsFloat | typing.SupportsIndex = 0.05, sigma: typing.SupportsFloat | typing.SupportsIndex = 0.02, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> dict:
    """
    Point-to-plane terms (as VoxelMap.point_to_plane returns them) of points_I (N, 3) placed by (R_WI, p_W) against fixed planes (N, 4) where valid (N,): the correspondences of VoxelMap.fit_planes kept fixed.
    """
def prepare_scan(points_L: typing.Any, t_points: typing.Any, knot_t: typing.Any, states: typing.Any, rates: typing.Any, t_ref: typing.SupportsFloat | typing.SupportsIndex, T_BI: typing.Any, T_BL: typing.Any, min_range: typing.SupportsFloat | typing.SupportsIndex, insert_voxel: typing.SupportsFloat | typing.SupportsIndex, scan_voxel: typing.SupportsFloat | typing.SupportsIndex, nthreads: typing.SupportsInt | typing.SupportsIndex = 0) -> tuple[numpy.typing.NDArray[numpy.float64], numpy.typing.NDArray[numpy.float64]]:
    """
    A LiDAR frame ready for registration in one call: deskew (same arguments), then points closer than min_range [m] dropped, voxel_downsample to insert_voxel [m] and that to scan_voxel [m], both in the LiDAR frame, then moved to the IMU frame. Returns (insert_I (M, 3), scan_I (S, 3)) float64.
    """
def voxel_downsample(points: typing.Any, voxel: typing.SupportsFloat | typing.SupportsIndex) -> numpy.typing.NDArray[numpy.float64]:
    """
    The centroid of the points (N, 3) in each occupied cubic voxel of edge `voxel` [m] (grid anchored at the origin), in the order the voxels are first seen.
    """

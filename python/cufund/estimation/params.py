"""Parameters of the LiDAR-inertial odometry (:class:`LioCore`, :class:`LioEstimator`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cufund.core.config import ConfigError, check_at_most, check_real_fields, from_dict, nested
from cufund.geometry import Transform
from cufund.sensors.imu import G0, ImuParams, imu_preset

__all__ = ["LioParams"]

_POSITIVE = (
    "init_duration_s",
    "accel_bias_sigma",
    "gyro_bias_sigma",
    "init_max_gyro_dev",
    "init_max_accel_dev",
    "gravity",
    "scan_voxel",
    "map_voxel",
    "map_insert_voxel",
    "map_max_distance",
    "plane_radius",
    "max_plane_rms",
    "max_residual",
    "robust_scale",
    "range_sigma",
    "convergence",
    "refit_distance",
    "lag_s",
    "lidar_information_scale",
    "relinearize_threshold",
    "bias_jump_deg",
    "bias_jump_m",
    "recovery_acc_rw",
    "recovery_gyro_rw",
    "health_max_lidar_gap_s",
)


_REMOVED = ("q_WB0", "pad_attitude_known")
"""Keys of earlier versions that gave flight software the true pad attitude."""


@dataclass(frozen=True)
class LioParams:
    """LiDAR-inertial odometry settings. SI units."""

    imu: ImuParams = field(default_factory=lambda: imu_preset("icm42688p"))
    """The IMU part: its noise spec sets the IMU factors' noise, its p_BI / q_BI the IMU extrinsic."""
    T_BL: Transform = field(default_factory=Transform)
    """LiDAR frame L -> body frame B."""
    p_WB0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The pad: the body's position there defines the world frame's origin [m] (the estimate starts here)."""
    pad_yaw: float = 0.0
    """The body's heading on the pad: it defines the world frame's yaw [rad]. Roll and pitch are not given: they
    are estimated from the mean specific force of the static window (the pad may be tilted), and the biases with
    them (gyroscope: the window's mean rate; accelerometer: zero, with ``accel_bias_sigma``), then refined in
    flight by the smoother."""
    accel_bias_sigma: float = 0.05
    """Prior standard deviation of the accelerometer bias left after the part's calibration, per axis [m/s^2]
    (a PX4-style calibration leaves a few mg). It also sets the prior on the initial roll and pitch
    (accel_bias_sigma / gravity [rad]): a bias along the horizontal is indistinguishable from a tilt on the pad."""
    gyro_bias_sigma: float = 1e-3
    """Prior standard deviation of the gyroscope bias about the static window's mean rate, per axis [rad/s]."""
    gravity: float = G0
    """[m/s^2]"""
    init_duration_s: float = 1.0
    """Static initialisation on the pad [s] (>= 1 s)."""
    init_max_gyro_dev: float = 0.05
    """Largest allowed |gyro - mean| during initialisation [rad/s]; more is motion: ValueError."""
    init_max_accel_dev: float = 0.5
    """Largest allowed |accel - mean| during initialisation [m/s^2]."""
    min_range: float = 0.3
    """Returns closer than this are dropped (the airframe) [m]."""
    scan_voxel: float = 0.3
    """Downsampling of the deskewed scan for registration [m]."""
    map_insert_voxel: float = 0.05
    """Downsampling of the deskewed scan added to the map [m]."""
    map_voxel: float = 0.25
    """Voxel edge of the map [m]; neighbour searches reach one voxel."""
    map_points_per_voxel: int = 6
    map_min_point_distance: float = 0.05
    """[m]"""
    map_max_distance: float = 40.0
    """Voxels farther than this from the vehicle are evicted [m]."""
    map_max_voxels: int = 200_000
    neighbours: int = 10
    """Map points per fitted plane."""
    plane_radius: float = 0.3
    """Neighbours farther than this are not used [m] (at most map_voxel)."""
    max_plane_rms: float = 0.05
    """[m]"""
    max_residual: float = 0.3
    """Point-to-plane distances beyond this are outliers [m]."""
    robust: str = "huber"
    """'none', 'huber' or 'cauchy'."""
    robust_scale: float = 0.05
    """[m]"""
    range_sigma: float = 0.02
    """Point-to-plane residual standard deviation [m] (about the LiDAR's range noise)."""
    max_iterations: int = 10
    """Gauss-Newton steps per set of correspondences."""
    max_refits: int = 3
    """Times the registration may re-find its correspondences."""
    convergence: float = 1e-4
    """Gauss-Newton stops when the step is below this [rad, m]."""
    degeneracy_threshold: float = 0.02
    """A direction of the registration Hessian is weakly observable when its eigenvalue, divided by the inlier
    count / range_sigma^2, is below this; it is left to the IMU."""
    lag_s: float = 1.0
    """Fixed-lag smoother window [s]."""
    lidar_information_scale: float = 1.0
    """Scales the LiDAR factor's information (points are not independent: < 1 is more honest)."""
    tightly_coupled: bool = True
    """True: the LiDAR factor re-finds correspondences and re-linearises the point-to-plane residuals whenever
    the smoother relinearises. False: a pose factor from the converged registration and its Hessian."""
    refit_distance: float = 0.01
    """The tightly coupled factor re-finds its correspondences when the pose has moved more than this since they
    were found [m] (rotations count as their displacement at one map voxel)."""
    smoother_iterations: int = 1
    """Smoother updates per scan (the first adds the factors, the rest re-linearise)."""
    relinearize_threshold: float = 0.001
    """ISAM2 relinearisation threshold [rad, m]."""
    nthreads: int = 0
    """Threads for the C++ kernels (0: all)."""
    bias_jump_deg: float = 0.5
    """A frame whose registered attitude is further than this from the IMU's prediction [deg] ..."""
    bias_jump_m: float = 0.05
    """... or whose registered position is further than this from it [m] takes a loose bias random walk in its
    IMU factor (recovery_*_rw), so the bias states can follow a bias jump."""
    recovery_acc_rw: float = 0.15
    """Accelerometer bias random walk of such a frame's IMU factor [m/s^2/sqrt(s)]."""
    recovery_gyro_rw: float = 0.05
    """Gyroscope bias random walk of such a frame's IMU factor [rad/s/sqrt(s)]."""
    health_max_lidar_gap_s: float = 0.35
    """Health: no LiDAR constraint for longer than this makes the estimate unhealthy (IMU only) [s]."""
    health_relock_frames: int = 3
    """Health: consistent LiDAR frames in a row needed to be healthy again after a gap or a disagreement."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "imu", nested(ImuParams, self.imu, "LioParams.imu"))
        if not isinstance(self.T_BL, Transform):
            if isinstance(self.T_BL, dict):
                object.__setattr__(self, "T_BL", Transform(**self.T_BL))
            else:
                raise ConfigError(f"LioParams.T_BL must be a Transform, got {type(self.T_BL).__name__}")
        check_real_fields(self, "LioParams", positive=True, names=_POSITIVE)
        if not (math.isfinite(self.min_range) and self.min_range >= 0):
            raise ConfigError(f"LioParams.min_range must be a finite number >= 0 [m], got {self.min_range!r}")
        if not (math.isfinite(self.degeneracy_threshold) and self.degeneracy_threshold >= 0):
            raise ConfigError("LioParams.degeneracy_threshold must be a finite number >= 0")
        if self.init_duration_s < 1.0:
            raise ConfigError(f"LioParams.init_duration_s must be >= 1 [s], got {self.init_duration_s!r}")
        if self.robust not in ("none", "huber", "cauchy"):
            raise ConfigError(f"LioParams.robust must be 'none', 'huber' or 'cauchy', got {self.robust!r}")
        for name, lo in (
            ("map_points_per_voxel", 1),
            ("map_max_voxels", 1),
            ("neighbours", 3),
            ("max_iterations", 1),
            ("max_refits", 0),
            ("health_relock_frames", 1),
            ("smoother_iterations", 1),
            ("nthreads", 0),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ConfigError(f"LioParams.{name} must be an integer >= {lo}, got {v!r}")
        check_at_most(
            self,
            "LioParams",
            init_duration_s=3600.0,
            map_points_per_voxel=1000,
            map_max_voxels=10**8,
            neighbours=1000,
            max_iterations=1000,
            max_refits=100,
            smoother_iterations=100,
            health_relock_frames=1000,
        )
        p = np.asarray(self.p_WB0, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ConfigError(f"LioParams.p_WB0 must be 3 finite numbers [m], got {self.p_WB0!r}")
        object.__setattr__(self, "p_WB0", tuple(float(v) for v in p))
        if (
            isinstance(self.pad_yaw, bool)
            or not isinstance(self.pad_yaw, (int, float))
            or not math.isfinite(self.pad_yaw)
        ):
            raise ConfigError(f"LioParams.pad_yaw must be a finite number [rad], got {self.pad_yaw!r}")
        check_at_most(self, "LioParams", accel_bias_sigma=10.0, gyro_bias_sigma=1.0)

    @classmethod
    def from_dict(cls, data: dict) -> LioParams:
        for old in _REMOVED:
            if isinstance(data, dict) and old in data:
                raise ConfigError(
                    f"LioParams.{old} was removed: the pad gives the world frame's origin (p_WB0) and yaw (pad_yaw) "
                    "only; roll, pitch and the biases are estimated from the static window"
                )
        return from_dict(cls, data, "LioParams")

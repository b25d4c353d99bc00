"""Parameters of the visual-inertial odometry (:class:`VioCore`, :class:`VioEstimator`) and its camera rig.

A camera here is the calibration a user knows (``camera_info``/Kalibr style): resolution, pinhole intrinsics
K, radial-tangential distortion (OpenCV's k1, k2, p1, p2, k3) and the mounting ``T_BC`` (camera frame C, FLU
like the body: x forward, y left, z up, as :mod:`cufund.sensors.camera`; images use the optical convention,
u right, v down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, check_at_most, check_real_fields, from_dict, nested
from cufund.geometry import Transform, quat_from_matrix
from cufund.sensors.imu import G0, ImuParams, imu_preset

__all__ = ["VioCamera", "VioParams", "camera_transform"]


def camera_transform(value: Any, where: str) -> Transform:
    """A camera mounting T_BC from a Transform, a ``{p|t: [x, y, z], q: [w, x, y, z]}`` mapping or a 4x4
    homogeneous matrix (Kalibr's form). A matrix whose 3x3 block is not a rotation (orthonormal, det +1, to
    1e-6) is a ConfigError naming ``where``: it is never silently re-orthonormalised."""
    if isinstance(value, Transform):
        return value
    if isinstance(value, dict):
        keys = set(value) - {"p", "t", "q"}
        if keys:
            raise ConfigError(f"{where}: unknown keys {sorted(keys)} (expected p or t [m], q [w, x, y, z])")
        q = np.asarray(value.get("q", (1.0, 0.0, 0.0, 0.0)), dtype=float)
        if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(float(np.linalg.norm(q)) - 1.0) > 1e-6:
            raise ConfigError(f"{where}.q must be a unit quaternion [w, x, y, z], got {value.get('q')!r}")
        try:
            p: Any = np.asarray(value.get("p", value.get("t", (0.0, 0.0, 0.0))), dtype=float)
            return Transform(tuple(p.reshape(-1).tolist()), tuple(q.tolist()))
        except TypeError:
            raise ConfigError(f"{where}.p must be 3 finite numbers [m], got {value!r}") from None
        except ValueError as e:
            raise ConfigError(f"{where}: {e}") from None
    try:
        M = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        M = np.full(1, np.nan)
    if M.shape != (4, 4) or not np.all(np.isfinite(M)):
        raise ConfigError(f"{where} must be a Transform, {{p, q}} or a finite 4x4 matrix, got {value!r}")
    R = M[:3, :3]
    if (
        np.abs(R.T @ R - np.eye(3)).max() > 1e-6
        or abs(float(np.linalg.det(R)) - 1.0) > 1e-6
        or np.abs(M[3] - [0, 0, 0, 1]).max() > 1e-12
    ):
        raise ConfigError(
            f"{where}: the rotation block is not a rotation (R^T R - I max {np.abs(R.T @ R - np.eye(3)).max():.3g}, "
            f"det {np.linalg.det(R):.6g}) or the last row is not [0, 0, 0, 1]"
        )
    return Transform(tuple(M[:3, 3]), tuple(quat_from_matrix(R)))


@dataclass(frozen=True)
class VioCamera:
    """One calibrated camera of the rig."""

    width: int = 640
    """[px]"""
    height: int = 480
    """[px]"""
    fx: float = 400.0
    """[px]"""
    fy: float = 400.0
    """[px]"""
    cx: float = 319.5
    """[px]"""
    cy: float = 239.5
    """[px]"""
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    """Radial-tangential (k1, k2, p1, p2, k3)."""
    T_BC: Transform = field(default_factory=Transform)
    """Camera frame C (FLU) -> body frame B."""

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 16 <= v <= 10_000:
                raise ConfigError(f"VioCamera.{name} must be an integer in [16, 10000] [px], got {v!r}")
        check_real_fields(self, "VioCamera", positive=True, names=("fx", "fy"))
        check_real_fields(self, "VioCamera", names=("cx", "cy"))
        d = np.asarray(self.distortion, dtype=float) if np.ndim(self.distortion) == 1 else np.full(1, np.nan)
        if d.shape != (5,) or not np.all(np.isfinite(d)):
            raise ConfigError(f"VioCamera.distortion must be 5 finite numbers, got {self.distortion!r}")
        object.__setattr__(self, "distortion", tuple(float(x) for x in d))
        object.__setattr__(self, "T_BC", camera_transform(self.T_BC, "VioCamera.T_BC"))

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @classmethod
    def from_dict(cls, data: dict) -> VioCamera:
        return from_dict(cls, data, "VioCamera")


_POSITIVE = (
    "gravity",
    "init_duration_s",
    "accel_bias_sigma",
    "gyro_bias_sigma",
    "init_max_gyro_dev",
    "init_max_accel_dev",
    "min_feature_distance_px",
    "klt_max_error",
    "stereo_epipolar_px",
    "stereo_fb_px",
    "stereo_min_ncc",
    "stereo_ncc_margin",
    "ransac_px",
    "pixel_sigma",
    "mono_pixel_sigma",
    "robust_k",
    "landmark_prior_sigma",
    "lag_s",
    "kf_max_interval_s",
    "relinearize_threshold",
    "covariance_every_s",
    "health_max_gap_s",
    "mono_min_parallax_deg",
    "max_depth",
    "min_depth",
)


@dataclass(frozen=True)
class VioParams:
    """Visual-inertial odometry settings. SI units, pixels where named ``_px``."""

    imu: ImuParams = field(default_factory=lambda: imu_preset("icm42688p"))
    """The IMU part: its datasheet noise sets the IMU factors' noise (never the true biases), q_BI / p_BI its mounting."""
    cam0: VioCamera = field(default_factory=VioCamera)
    """Left (reference) camera."""
    cam1: VioCamera | None = field(
        default_factory=lambda: VioCamera(T_BC=Transform((0.0, -0.1, 0.0), (1.0, 0.0, 0.0, 0.0)))
    )
    """Right camera of a stereo pair; None: monocular + IMU (landmarks triangulated from keyframes with
    ``mono_min_parallax_deg`` of parallax, the scale from the IMU factors)."""
    cameras: str = "stereo"
    """``stereo``: both cameras of the rig (cam0 left, cam1 right); ``mono``: cam0 alone with the IMU (cam1 is then
    None; a scenario's ``stereo_camera`` rig gives its left camera). A ``cam1`` of None also means ``mono``."""
    p_WB0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The pad: the body's position there is the world frame's origin [m]."""
    pad_yaw: float = 0.0
    """The body's heading on the pad: the world frame's yaw [rad] (roll and pitch are estimated from gravity)."""
    gravity: float = G0
    """[m/s^2]"""
    init_duration_s: float = 1.0
    """Static initialisation on the pad [s]: gravity direction and gyroscope bias from its mean (>= 1 s)."""
    init_max_gyro_dev: float = 0.05
    """[rad/s] larger |gyro - mean| in the static window is motion: ValueError."""
    init_max_accel_dev: float = 0.5
    """[m/s^2]"""
    accel_bias_sigma: float = 0.05
    """Prior sigma of the accelerometer bias per axis [m/s^2] (also the initial tilt prior, / gravity)."""
    gyro_bias_sigma: float = 1e-3
    """Prior sigma of the gyroscope bias about the static mean [rad/s]."""
    max_features: int = 150
    """Features tracked per frame (new corners are detected when fewer remain)."""
    min_feature_distance_px: float = 20.0
    """Smallest distance between two tracked features [px]."""
    klt_window_px: int = 21
    klt_levels: int = 3
    klt_max_error: float = 30.0
    """KLT tracks whose error is above this are dropped."""
    stereo_epipolar_px: float = 1.5
    """Stereo matches further than this from the epipolar line (rectified rows) are rejected [px]."""
    stereo_fb_px: float = 0.5
    """A stereo match is kept only if KLT tracks it back from the right image to within this of the left
    feature [px] (a match that slid onto another patch of the row does not come back)."""
    stereo_patch_px: int = 11
    """Side of the patch the stereo row search correlates [px] (odd)."""
    stereo_min_ncc: float = 0.5
    """The row search's best normalised cross-correlation must reach this, in (0, 1] ..."""
    stereo_ncc_margin: float = 0.05
    """... and beat every other peak on the row (outside its own lobe) by this: an ambiguous match (a repetitive
    texture) is dropped."""
    ransac_px: float = 1.5
    """Reprojection threshold of the temporal RANSAC (PnP on the previous frame's stereo points) [px]."""
    min_depth: float = 0.2
    """[m] stereo points nearer than this are not used."""
    max_depth: float = 30.0
    """[m] stereo points farther than this are not used."""
    pixel_sigma: float = 0.5
    """Stereo measurement noise per coordinate [px]. 0.3 helped bench_vio's vio_room flight (3.03 -> 2.82 cm) and
    square_vio (12.1 -> 10.6 mm) but the tunnel on VIO then hit a frame at 14.4 s: kept at 0.5."""
    mono_pixel_sigma: float = 0.5
    """Monocular measurement noise per coordinate [px] (0.3 made bench_vio's mono flight worse, 11.7 -> 15.8 cm)."""
    robust_k: float = 2.0
    """Huber threshold of the stereo factors, in sigmas."""
    landmark_prior_sigma: float = 2.0
    """A weak prior on each new landmark at its stereo triangulation [m]: it keeps a landmark determined when its
    stereo factors give nothing (GTSAM zeroes a factor whose point lies behind the camera)."""
    mono_min_parallax_deg: float = 2.0
    """Monocular: a track becomes a landmark once its rays from two keyframes in the window part by this angle
    [deg] (a smaller one triangulates a depth the pixel noise decides)."""
    kf_max_interval_s: float = 0.1
    """A frame becomes a keyframe (a smoother state) at least this often [s] ..."""
    kf_min_parallax_px: float = 40.0
    """... or when the tracked features moved this much on average since the last keyframe [px] ..."""
    kf_min_tracked_ratio: float = 0.6
    """... or when fewer than this fraction of the last keyframe's features are still tracked."""
    lag_s: float = 1.5
    """Fixed-lag smoother window [s]."""
    relinearize_threshold: float = 0.001
    """ISAM2 relinearisation threshold [rad, m]."""
    covariance_every_s: float = 1.0
    """The newest keyframe's position covariance is computed (diagnostics' sigma) at most this often while vision
    is good, and at every keyframe without visual constraint [s] (it costs tens of ms in a full window)."""
    time_offset_s: float = 0.0
    """Known camera-IMU time shift (Kalibr's timeshift_cam_imu: t_imu = t_cam + shift) [s], applied to every frame."""
    estimate_time_offset: bool = True
    """Estimate the remaining camera-IMU offset online (gyro rotation vs visual rotation between frames; reported
    in the diagnostics, not applied)."""
    health_min_inliers: int = 15
    """A frame with fewer temporal inliers adds no trusted visual constraint (unhealthy)."""
    health_max_gap_s: float = 0.3
    """No trusted visual constraint for longer than this: unhealthy (IMU only) [s]."""
    health_relock_frames: int = 3
    """Good frames in a row needed to be healthy again."""
    health_max_imu_chi2: float | None = None
    """The consistency check: unhealthy when the IMU factors' chi-square at the smoother's estimate, averaged over
    the last ``health_chi2_keyframes`` keyframes (the median: a single correction when texture returns after a gap
    is no disagreement), exceeds this (the camera's motion is not the IMU's: a wrong stereo
    baseline or extrinsic, drifting tracks; the inlier count does not see it). None: off (the default; its scale
    depends on how well the IMU spec matches the part: about 0.01 on a correct rig in the synthetic room,
    0.5 with a baseline 25 % too long)."""
    health_chi2_keyframes: int = 10
    """Keyframes averaged by that check."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "imu", nested(ImuParams, self.imu, "VioParams.imu"))
        object.__setattr__(self, "cam0", nested(VioCamera, self.cam0, "VioParams.cam0"))
        if self.cameras not in ("stereo", "mono"):
            raise ConfigError(f"VioParams.cameras must be 'stereo' or 'mono', got {self.cameras!r}")
        if self.cameras == "mono":
            object.__setattr__(self, "cam1", None)
        elif self.cam1 is None:
            object.__setattr__(self, "cameras", "mono")
        if self.cam1 is not None:
            object.__setattr__(self, "cam1", nested(VioCamera, self.cam1, "VioParams.cam1"))
            if (self.cam1.width, self.cam1.height) != (self.cam0.width, self.cam0.height):
                raise ConfigError("VioParams.cam1 must have cam0's resolution")
        check_real_fields(self, "VioParams", positive=True, names=_POSITIVE)
        check_real_fields(self, "VioParams", names=("kf_min_parallax_px", "kf_min_tracked_ratio", "time_offset_s"))
        if self.init_duration_s < 1.0:
            raise ConfigError(f"VioParams.init_duration_s must be >= 1 [s], got {self.init_duration_s!r}")
        if not self.min_depth < self.max_depth:
            raise ConfigError("VioParams.min_depth must be below max_depth")
        for name, lo in (
            ("max_features", 8),
            ("klt_window_px", 5),
            ("klt_levels", 0),
            ("stereo_patch_px", 3),
            ("health_min_inliers", 3),
            ("health_relock_frames", 1),
            ("health_chi2_keyframes", 1),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ConfigError(f"VioParams.{name} must be an integer >= {lo}, got {v!r}")
        if self.health_max_imu_chi2 is not None:
            check_real_fields(self, "VioParams", positive=True, names=("health_max_imu_chi2",))
        check_at_most(
            self,
            "VioParams",
            max_features=5000,
            klt_window_px=101,
            klt_levels=8,
            kf_min_tracked_ratio=1.0,
            stereo_patch_px=101,
            stereo_min_ncc=1.0,
        )
        if self.stereo_patch_px % 2 == 0:
            raise ConfigError(f"VioParams.stereo_patch_px must be odd, got {self.stereo_patch_px}")
        if not isinstance(self.estimate_time_offset, bool):
            raise ConfigError("VioParams.estimate_time_offset must be true or false")
        p = np.asarray(self.p_WB0, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ConfigError(f"VioParams.p_WB0 must be 3 finite numbers [m], got {self.p_WB0!r}")
        object.__setattr__(self, "p_WB0", tuple(float(v) for v in p))
        if (
            isinstance(self.pad_yaw, bool)
            or not isinstance(self.pad_yaw, (int, float))
            or not math.isfinite(self.pad_yaw)
        ):
            raise ConfigError(f"VioParams.pad_yaw must be a finite number [rad], got {self.pad_yaw!r}")

    @classmethod
    def from_dict(cls, data: dict) -> VioParams:
        return from_dict(cls, data, "VioParams")

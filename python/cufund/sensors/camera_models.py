"""Camera intrinsics and lens models as users know them (ROS ``camera_info``, OpenCV, Kalibr).

:class:`CameraIntrinsics` is the pinhole matrix K (fx, fy, cx, cy), the resolution and a distortion model:

- ``radtan`` (OpenCV's default, Kalibr's ``radtan``, ROS's ``plumb_bob``): D = (k1, k2, p1, p2, k3);
- ``equidistant`` (OpenCV's ``cv2.fisheye``, Kalibr's ``pinhole-equi``): D = (k1, k2, k3, k4),
  θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸) with θ = atan(r).

Both map undistorted normalised coordinates (x, y) = (X/Z, Y/Z) of a point in the optical frame O (x right,
y down, z forward) to distorted ones, then pixels u = fx x_d + cx, v = fy y_d + cy (pixel centres at integers).
:class:`CameraCalibration` adds the camera's mounting ``T_BC`` (camera frame C, FLU like the body) and its clock
offset, i.e. one camera of a calibrated rig (see :mod:`cufund.sensors.kalibr`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from cufund.geometry import Transform

# Optical frame O (x right, y down, z forward) -> camera frame C (x forward, y left, z up).
R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])

DISTORTION_MODELS = {"radtan": 5, "equidistant": 4}
"""Distortion model -> number of coefficients."""


def _real(name: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number [px], got {v!r}")
    return float(v)


@dataclasses.dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics, resolution and lens distortion (``camera_info``'s K, D, model, width, height)."""

    width: int
    """Image width [px]."""
    height: int
    """Image height [px]."""
    fx: float
    """Focal length in pixels along u [px]."""
    fy: float
    """Focal length in pixels along v [px]."""
    cx: float
    """Principal point u [px]."""
    cy: float
    """Principal point v [px]."""
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    """Coefficients of ``distortion_model``: radtan (k1, k2, p1, p2, k3), OpenCV's order (4 values: k3 = 0);
    equidistant (k1, k2, k3, k4)."""
    distortion_model: str = "radtan"
    """``radtan`` or ``equidistant`` (fisheye, Kalibr's pinhole-equi)."""

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float, np.integer, np.floating))
                or not 1 <= v <= 100_000
                or int(v) != v
            ):
                raise ValueError(f"{name} must be a positive integer [px], got {v}")
            object.__setattr__(self, name, int(v))
        for name in ("fx", "fy", "cx", "cy"):
            object.__setattr__(self, name, _real(name, getattr(self, name)))
        for name in ("fx", "fy"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0 [px], got {v}")
        for name in ("cx", "cy"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite [px]")
        if self.distortion_model not in DISTORTION_MODELS:
            raise ValueError(
                f"distortion_model must be one of {', '.join(DISTORTION_MODELS)}, got {self.distortion_model!r}"
            )
        n = DISTORTION_MODELS[self.distortion_model]
        try:
            d = np.asarray(self.distortion, dtype=float)
        except (TypeError, ValueError):
            d = np.full(1, np.nan)  # reported below
        if self.distortion_model == "radtan" and d.shape == (4,):
            d = np.append(d, 0.0)
        if d.shape != (n,) or not np.all(np.isfinite(d)):
            what = "(k1, k2, p1, p2, k3)" if n == 5 else "(k1, k2, k3, k4)"
            raise ValueError(
                f"distortion must be {n} finite numbers {what} for the {self.distortion_model} model, "
                f"got {self.distortion!r}"
            )
        object.__setattr__(self, "distortion", tuple(float(x) for x in d))

    @classmethod
    def from_fov(cls, width: int, height: int, hfov: float) -> CameraIntrinsics:
        """Square pixels, principal point at the image centre, horizontal field of view ``hfov`` [rad]."""
        if not 0 < hfov < np.pi:
            raise ValueError(f"hfov must be in (0, π) [rad], got {hfov}")
        f = (width / 2) / np.tan(hfov / 2)
        return cls(width, height, f, f, (width - 1) / 2, (height - 1) / 2)

    @property
    def K(self) -> np.ndarray:
        """(3, 3) camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def camera_info(self) -> dict[str, Any]:
        """ROS ``sensor_msgs/CameraInfo``-style fields: width, height, distortion_model (``plumb_bob`` or
        ``equidistant``), D, K (row-major 9)."""
        model = "plumb_bob" if self.distortion_model == "radtan" else "equidistant"
        return {
            "width": self.width,
            "height": self.height,
            "distortion_model": model,
            "D": list(self.distortion),
            "K": [float(x) for x in self.K.ravel()],
        }

    @classmethod
    def from_camera_info(cls, info: Any) -> CameraIntrinsics:
        """From ROS ``camera_info`` fields: width, height, K (9 numbers, row-major), D and distortion_model
        (plumb_bob, radtan or equidistant); the inverse of :meth:`camera_info`."""
        if not isinstance(info, dict):
            raise ValueError(f"camera_info must be a mapping with width, height, K, D, distortion_model, got {info!r}")
        missing = [k for k in ("width", "height", "K") if k not in info]
        if missing:
            raise ValueError(f"camera_info: missing key {missing[0]!r}")
        try:
            K = np.asarray(info["K"], dtype=float).reshape(3, 3)
        except (TypeError, ValueError):
            raise ValueError(f"camera_info.K must be 9 numbers (row-major 3x3), got {info['K']!r}") from None
        if K[0, 1] != 0.0 or np.any(K[2] != (0.0, 0.0, 1.0)) or K[1, 0] != 0.0:
            raise ValueError(f"camera_info.K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], got {K.tolist()}")
        model = info.get("distortion_model", "plumb_bob")
        models = {"plumb_bob": "radtan", "radtan": "radtan", "equidistant": "equidistant"}
        if not isinstance(model, str) or model not in models:
            raise ValueError(f"camera_info.distortion_model must be one of {', '.join(models)}, got {model!r}")
        n = DISTORTION_MODELS[models[model]]
        D = info.get("D") or [0.0] * n
        return cls(info["width"], info["height"], K[0, 0], K[1, 1], K[0, 2], K[1, 2], tuple(D), models[model])

    def project(self, p_O: np.ndarray) -> np.ndarray:
        """(N, 3) points in the optical frame (z > 0) -> (N, 2) distorted pixel coordinates (u, v)."""
        p_O = np.asarray(p_O, dtype=float)
        x, y = p_O[:, 0] / p_O[:, 2], p_O[:, 1] / p_O[:, 2]
        xd, yd = self.distort(x, y)
        return np.stack([self.fx * xd + self.cx, self.fy * yd + self.cy], 1)

    def distort(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Undistorted normalised coordinates -> distorted ones, under ``distortion_model``."""
        if self.distortion_model == "equidistant":
            k1, k2, k3, k4 = self.distortion
            r = np.hypot(x, y)
            th = np.arctan(r)
            t2 = th * th
            thd = th * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
            s = np.where(r > 1e-12, thd / np.where(r > 1e-12, r, 1.0), 1.0)
            return x * s, y * s
        k1, k2, p1, p2, k3 = self.distortion
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        return (
            x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y,
        )

    # kept for callers of the 0.x name
    _distort = distort

    def undistort(self, xd: np.ndarray, yd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distorted normalised coordinates -> undistorted ones (fixed-point for radtan, Newton on θ for
        equidistant; exact when the distortion is zero)."""
        xd, yd = np.asarray(xd, dtype=float), np.asarray(yd, dtype=float)
        if not any(self.distortion):
            return xd.copy(), yd.copy()
        if self.distortion_model == "equidistant":
            k1, k2, k3, k4 = self.distortion
            thd = np.hypot(xd, yd)
            th = thd.copy()
            for _ in range(20):
                t2 = th * th
                f = th * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - thd
                df = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
                th = th - f / df
            th = np.clip(th, 0.0, np.pi / 2 - 1e-6)
            s = np.where(thd > 1e-12, np.tan(th) / np.where(thd > 1e-12, thd, 1.0), 1.0)
            return xd * s, yd * s
        k1, k2, p1, p2, k3 = self.distortion
        x, y = xd.copy(), yd.copy()
        for _ in range(30):
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            x = (xd - 2 * p1 * x * y - p2 * (r2 + 2 * x * x)) / radial
            y = (yd - p1 * (r2 + 2 * y * y) - 2 * p2 * x * y) / radial
        return x, y

    def pixel_directions(self) -> np.ndarray:
        """(H, W, 3) ray directions (x_n, y_n, 1) in the optical frame through each pixel centre."""
        u, v = np.meshgrid(np.arange(self.width, dtype=float), np.arange(self.height, dtype=float))
        x, y = self.undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy)
        return np.stack([x, y, np.ones_like(x)], -1)


def _transform(value: Any, name: str) -> Transform:
    """A Transform from itself, {p, q} / {t, q}, or a 4x4 homogeneous matrix; rejects non-rotations."""
    if isinstance(value, Transform):
        return value
    if isinstance(value, dict):
        unknown = sorted(set(value) - {"p", "t", "q"})
        if unknown:
            raise ValueError(f"{name}: unknown key {unknown[0]!r}; expected p [m] and q [w, x, y, z]")
        p = value.get("p", value.get("t", (0.0, 0.0, 0.0)))
        q = value.get("q", (1.0, 0.0, 0.0, 0.0))
        try:
            qa = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name}.q must be 4 numbers [w, x, y, z], got {q!r}") from None
        if qa.shape != (4,) or not np.all(np.isfinite(qa)) or abs(np.linalg.norm(qa) - 1.0) > 1e-6:
            raise ValueError(f"{name}.q must be a finite unit quaternion [w, x, y, z] (a rotation), got {q!r}")
        try:
            return Transform(p, q)  # type: ignore[arg-type]
        except (TypeError, ValueError) as e:
            raise ValueError(f"{name}: {e}") from None
    return transform_from_matrix(value, name)


def transform_from_matrix(value: Any, name: str) -> Transform:
    """A Transform from a 4x4 homogeneous matrix [[R, t], [0 0 0 1]]; R must be a rotation (orthonormal,
    det +1, within 1e-6)."""
    from cufund.geometry import quat_from_matrix

    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a 4x4 matrix of numbers, got {value!r}") from None
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{name} must be a 4x4 matrix of finite numbers, got shape {T.shape}: {value!r}")
    if not np.allclose(T[3], (0.0, 0.0, 0.0, 1.0), atol=1e-9):
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1], got {T[3].tolist()}")
    R = T[:3, :3]
    err = np.abs(R @ R.T - np.eye(3)).max()
    if err > 1e-6 or np.linalg.det(R) < 0:
        raise ValueError(
            f"{name}: the 3x3 block must be a rotation (orthonormal, det +1), got |R R^T - I| = {err:.3g}, "
            f"det = {np.linalg.det(R):.6g}"
        )
    q = quat_from_matrix(R)
    return Transform((float(T[0, 3]), float(T[1, 3]), float(T[2, 3])), tuple(float(x) for x in q))  # type: ignore[arg-type]


@dataclasses.dataclass(frozen=True)
class CameraCalibration:
    """One calibrated camera of a rig: intrinsics, mounting on the body and clock offset."""

    intrinsics: CameraIntrinsics
    T_BC: Transform = Transform()
    """Camera frame C (FLU: x along the optical axis, y left, z up) in the body frame B."""
    timeshift_s: float = 0.0
    """Kalibr's ``timeshift_cam_imu``: t_imu = t_cam + timeshift_s [s]."""
    name: str = "cam0"

    def __post_init__(self) -> None:
        if not isinstance(self.intrinsics, CameraIntrinsics):
            raise ValueError(f"intrinsics must be a CameraIntrinsics, got {type(self.intrinsics).__name__}")
        object.__setattr__(self, "T_BC", _transform(self.T_BC, f"{self.name}.T_BC"))
        ts = self.timeshift_s
        if isinstance(ts, bool) or not isinstance(ts, (int, float, np.integer, np.floating)) or not np.isfinite(ts):
            raise ValueError(f"{self.name}.timeshift_s must be a finite number [s], got {ts!r}")
        object.__setattr__(self, "timeshift_s", float(ts))

    @property
    def T_BO(self) -> Transform:
        """The optical frame O (x right, y down, z forward) in the body frame."""
        from cufund.geometry import quat_from_matrix

        q_CO = quat_from_matrix(R_CO)
        return self.T_BC @ Transform((0.0, 0.0, 0.0), tuple(float(x) for x in q_CO))  # type: ignore[arg-type]

"""What crosses the estimator's boundary: GTSAM's poses and the PointCloud message's time layout.

GTSAM's ``Rot3.toQuaternion().coeffs()`` is [x, y, z, w] (Eigen's order) while cufund's quaternions are
[w, x, y, z]; poses cross to and from GTSAM here as matrices only, so no quaternion ordering can go wrong.
Rotations themselves are :mod:`cufund.geometry`'s.
"""

from __future__ import annotations

import warnings
from typing import Any

import gtsam
import numpy as np

__all__ = ["pose3", "pose3_parts", "scan_frame"]


def pose3(R_WB: np.ndarray, p_W: np.ndarray) -> gtsam.Pose3:
    """The gtsam Pose3 of rotation R_WB (3, 3) and position p_W (3,)."""
    return gtsam.Pose3(gtsam.Rot3(np.asarray(R_WB, dtype=float)), np.asarray(p_W, dtype=float))


def pose3_parts(T_WB: gtsam.Pose3) -> tuple[np.ndarray, np.ndarray]:
    """(R_WB (3, 3), p_W (3,)) of a gtsam Pose3 (matrices only: no quaternion ordering to get wrong)."""
    return T_WB.rotation().matrix(), np.asarray(T_WB.translation(), dtype=float)


def scan_frame(cloud: Any) -> tuple[float, np.ndarray, np.ndarray]:
    """(frame start t [s], per-point offsets dt (N,) [s], points_L (N, 3)) of a PointCloud, from either its
    current shape (t, dt) or the older one (t0, absolute per-point t)."""
    if hasattr(cloud, "dt"):
        t = float(cloud.t)
        return t, np.asarray(cloud.dt, dtype=float), np.asarray(cloud.points_L)
    t0 = float(cloud.t0)
    return t0, np.asarray(cloud.t, dtype=float) - t0, np.asarray(cloud.points_L)


_TO_GEOMETRY = ("quat_from_matrix", "matrix_from_quat", "homogeneous")
"""Names cufund.estimation.frames (0.1; this module's old path) held that are rotations, now in cufund.geometry."""


def __getattr__(name: str) -> Any:
    if name in _TO_GEOMETRY:
        warnings.warn(
            f"cufund.estimation.frames.{name} moved to cufund.geometry; the old path goes in the next release",
            DeprecationWarning,
            stacklevel=2,
        )
        from cufund import geometry

        return getattr(geometry, name)
    raise AttributeError(f"module 'cufund.estimation.boundary' has no attribute {name!r}")

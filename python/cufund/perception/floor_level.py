"""The floor as the detector's level: a plane fitted to the LiDAR's returns around the pad, and the rigid motion
that makes it the plane z = floor_z.

A detector that assumes frames stand on a level floor at a known height must not take the estimated world frame's
horizontal for that floor: the estimator's roll and pitch on the pad come from the accelerometer, whose residual
bias after calibration tilts the frame by bias / g (3 mg: 0.17 deg, 3 cm over 10 m), and a pad may stand on a
slope. The floor the LiDAR sees is the reference the detector's assumption is about, so the detector measures in
the floor's frame D, x_D = R_DW (x_W - o_W) + o_W + h e_z, with R_DW the smallest rotation taking the fitted floor
normal to +z about ``o_W`` (the floor below the pad) and h the offset that puts the floor at ``floor_z``.
"""

from __future__ import annotations

import math

import numpy as np

from cufund.geometry import quat_from_two_vectors, quat_to_matrix

__all__ = ["FloorLevel", "fit_floor"]


class FloorLevel:
    """The rigid motion from the estimated world frame W to the detector's floor frame D (identity by default)."""

    def __init__(self, R_DW: np.ndarray | None = None, o_W: np.ndarray | None = None, h: float = 0.0) -> None:
        self.R_DW = np.eye(3) if R_DW is None else np.asarray(R_DW, dtype=float)
        self.o_W = np.zeros(3) if o_W is None else np.asarray(o_W, dtype=float)
        self.h = float(h)

    @property
    def tilt_deg(self) -> float:
        """Angle between the world's z axis and the floor's normal [deg]."""
        return math.degrees(math.acos(float(np.clip(self.R_DW[2, 2], -1.0, 1.0))))

    def pose_to_D(self, p_W: np.ndarray, R_W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (..., 3) and rotations (..., 3, 3) given in W, expressed in D."""
        p_D = (np.asarray(p_W) - self.o_W) @ self.R_DW.T + self.o_W + np.array([0.0, 0.0, self.h])
        return p_D, np.einsum("ij,...jk->...ik", self.R_DW, np.asarray(R_W))

    def point_to_W(self, x_D: np.ndarray) -> np.ndarray:
        """Points (..., 3) in D, expressed in W."""
        return (np.asarray(x_D) - self.o_W - np.array([0.0, 0.0, self.h])) @ self.R_DW + self.o_W

    def vector_to_W(self, v_D: np.ndarray) -> np.ndarray:
        """Directions (..., 3) in D, expressed in W."""
        return np.asarray(v_D) @ self.R_DW


def fit_floor(
    points_W: np.ndarray, o_W: np.ndarray, floor_z: float, band: float = 0.25, max_tilt_deg: float = 5.0
) -> FloorLevel | None:
    """The :class:`FloorLevel` of the plane z = a x + b y + c fitted to ``points_W`` (N, 3) within ``band`` [m] of
    ``floor_z`` (least squares, again on the points within 3 sigma of the fit, the sigma from the residuals'
    median absolute deviation, until none falls away: the feet of frames and walls go), about the pad ``o_W``; None with fewer than 500 points on it, or a plane tilted more than
    ``max_tilt_deg`` (no floor in view: the identity stays)."""
    pts = np.asarray(points_W, dtype=float).reshape(-1, 3)
    pts = pts[np.abs(pts[:, 2] - floor_z) < band]
    for _ in range(6):
        if len(pts) < 500:
            return None
        A = np.column_stack([pts[:, 0] - o_W[0], pts[:, 1] - o_W[1], np.ones(len(pts))])
        coef, *_ = np.linalg.lstsq(A, pts[:, 2], rcond=None)
        r = pts[:, 2] - A @ coef
        sigma = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), 2e-3)  # robust: the MAD
        inliers = np.abs(r) < 3.0 * sigma
        if inliers.all():
            break
        pts = pts[inliers]
    a, b, c = (float(v) for v in coef)
    n = np.array([-a, -b, 1.0]) / math.sqrt(a * a + b * b + 1.0)  # the floor's upward normal in W
    if math.degrees(math.acos(float(n[2]))) > max_tilt_deg:
        return None
    R = quat_to_matrix(quat_from_two_vectors(n, np.array([0.0, 0.0, 1.0])))  # the shortest turn of n onto +z
    # pivot on the floor below the pad, (o_x, o_y, c): every floor point lands on z = c + h = floor_z in D
    return FloorLevel(R, np.array([float(o_W[0]), float(o_W[1]), c]), floor_z - c)

"""Odometry error figures (the issue's metrics.json fields) and TUM trajectory files for checking with ``evo``.

Errors are taken at each estimate's stamp against the true pose at the same time: unaligned (the estimator's world
frame is the pad's: origin and yaw) and, with :func:`aligned_ate`, after evo's SE(3) alignment.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["aligned_ate", "flight_window", "odometry_errors", "read_tum", "write_tum"]


def odometry_errors(p_est: np.ndarray, q_est: np.ndarray, p_true: np.ndarray, q_true: np.ndarray) -> dict[str, float]:
    """``odometry_min_m``, ``odometry_rmse_m``, ``odometry_max_m`` (|p_true - p_est|) and ``odometry_rot_rmse_deg``
    (angle of R_est^T R_true) over matching rows of positions (N, 3) and quaternions (N, 4) [w, x, y, z]."""
    p_est, p_true = np.asarray(p_est, float), np.asarray(p_true, float)
    if p_est.shape != p_true.shape or p_est.ndim != 2 or p_est.shape[1] != 3 or len(p_est) == 0:
        raise ValueError(f"p_est and p_true must be the same (N, 3) with N > 0, got {p_est.shape}, {p_true.shape}")
    e = np.linalg.norm(p_est - p_true, axis=1)
    qe, qt = np.asarray(q_est, float), np.asarray(q_true, float)
    ang = (Rotation.from_quat(qe[:, [1, 2, 3, 0]]).inv() * Rotation.from_quat(qt[:, [1, 2, 3, 0]])).magnitude()
    return {
        "odometry_min_m": float(e.min()),
        "odometry_rmse_m": float(np.sqrt(np.mean(e**2))),
        "odometry_max_m": float(e.max()),
        "odometry_rot_rmse_deg": float(np.degrees(np.sqrt(np.mean(ang**2)))),
    }


def aligned_ate(p_est: np.ndarray, p_true: np.ndarray) -> float:
    """Absolute trajectory error [m] after the rigid alignment that fits the estimate to the truth best (Umeyama's
    least-squares rotation and translation, no scale): the RMSE of |p_true - (R p_est + t)| over matching rows of
    positions (N, 3), N >= 3. This is evo's APE of the translation part with ``--align`` (SE(3) Umeyama)."""
    p_est, p_true = np.asarray(p_est, float), np.asarray(p_true, float)
    if p_est.shape != p_true.shape or p_est.ndim != 2 or p_est.shape[1] != 3 or len(p_est) < 3:
        raise ValueError(f"p_est and p_true must be the same (N, 3) with N >= 3, got {p_est.shape}, {p_true.shape}")
    if not (np.all(np.isfinite(p_est)) and np.all(np.isfinite(p_true))):
        raise ValueError("p_est and p_true must be finite")
    mu_e, mu_t = p_est.mean(axis=0), p_true.mean(axis=0)
    cov = (p_true - mu_t).T @ (p_est - mu_e) / len(p_est)
    u, _, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:  # a reflection is not a rotation
        s[2, 2] = -1.0
    R = u @ s @ vt
    t = mu_t - R @ mu_e
    e = np.linalg.norm(p_true - (p_est @ R.T + t), axis=1)
    return float(np.sqrt(np.mean(e**2)))


def flight_window(z_true: np.ndarray, lift_m: float = 0.05) -> slice:
    """The rows from take-off to touchdown: from the first true height more than ``lift_m`` [m] above the first row's
    (the pad) to the last such row (an empty slice when the vehicle never lifts off)."""
    z = np.asarray(z_true, float)
    up = np.flatnonzero(z > z[0] + lift_m) if len(z) else np.array([], int)
    return slice(int(up[0]), int(up[-1]) + 1) if len(up) else slice(0, 0)


def write_tum(path: str | Path, t: np.ndarray, p_W: np.ndarray, q_WB: np.ndarray) -> None:
    """TUM trajectory file: one line ``t x y z qx qy qz qw`` per pose (q given as [w, x, y, z])."""
    q = np.asarray(q_WB, float)
    rows = np.column_stack([np.asarray(t, float), np.asarray(p_W, float), q[:, 1:4], q[:, 0]])
    np.savetxt(path, rows, fmt="%.9f")


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (N,), p_W (N, 3), q_WB (N, 4) [w, x, y, z]) from a TUM file."""
    rows = np.atleast_2d(np.loadtxt(path))
    return rows[:, 0], rows[:, 1:4], np.column_stack([rows[:, 7], rows[:, 4:7]])

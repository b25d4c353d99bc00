"""Rotations, rigid transforms and the GTSAM boundary: the ONE place quaternions are converted.

cufund's quaternions are [w, x, y, z]; GTSAM's ``Rot3.toQuaternion().coeffs()`` is [x, y, z, w] (Eigen's order),
so nothing else in this package touches gtsam quaternions.
"""

from __future__ import annotations

import math

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from cufund.sensors.pose import Transform

__all__ = ["quat_from_matrix", "matrix_from_quat", "pose3", "pose3_parts", "homogeneous", "scan_frame"]


def matrix_from_quat(q_wxyz: np.ndarray) -> np.ndarray:
    """(…, 4) [w, x, y, z] (normalised here) -> (…, 3, 3)."""
    q = np.asarray(q_wxyz, dtype=float)
    if q.shape == (4,):  # one quaternion: plain arithmetic (the per-IMU-sample path)
        w, x, y, z = (q / math.sqrt(float(q @ q))).tolist()
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """(3, 3) -> (4,) [w, x, y, z] with w >= 0 (Shepperd's method; a fast path for one matrix), or (…, 3, 3) ->
    (…, 4) through scipy."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        q = Rotation.from_matrix(R).as_quat()[..., [3, 0, 1, 2]]
        return np.where(q[..., :1] < 0, -q, q)
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = R.tolist()
    tr = m00 + m11 + m22
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    out = np.array(q)
    out /= np.linalg.norm(out)
    return -out if out[0] < 0 else out


def pose3(R: np.ndarray, p: np.ndarray) -> gtsam.Pose3:
    return gtsam.Pose3(gtsam.Rot3(np.asarray(R, dtype=float)), np.asarray(p, dtype=float))


def pose3_parts(T: gtsam.Pose3) -> tuple[np.ndarray, np.ndarray]:
    """(R (3, 3), p (3,)) of a gtsam Pose3 (matrices only: no quaternion ordering to get wrong)."""
    return T.rotation().matrix(), np.asarray(T.translation(), dtype=float)


def homogeneous(T: Transform) -> np.ndarray:
    """4x4 matrix of a cufund Transform (T_AB: B -> A)."""
    M = np.eye(4)
    M[:3, :3] = matrix_from_quat(np.asarray(T.q))
    M[:3, 3] = T.t
    return M


def scan_frame(cloud: object) -> tuple[float, np.ndarray, np.ndarray]:
    """(frame start t [s], per-point offsets dt (N,) [s], points_L (N, 3)) of a PointCloud, from either its
    current shape (t, dt) or the older one (t0, absolute per-point t)."""
    if hasattr(cloud, "dt"):
        t = float(cloud.t)
        return t, np.asarray(cloud.dt, dtype=float), np.asarray(cloud.points_L)
    t0 = float(cloud.t0)
    return t0, np.asarray(cloud.t, dtype=float) - t0, np.asarray(cloud.points_L)

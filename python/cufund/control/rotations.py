"""Small rotation helpers for controllers (quaternions [w, x, y, z], Hamilton product, body to world)."""

from __future__ import annotations

import math

import numpy as np

from cufund import _core

__all__ = ["cross", "quat_multiply", "quat_conjugate", "quat_to_rotation", "rotation_to_quat", "quat_from_two_vectors",
           "attitude_from_thrust_and_yaw", "yaw_of"]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (np.cross is slow for single vectors)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def quat_to_rotation(q: np.ndarray) -> np.ndarray:
    """R (3, 3) of a unit quaternion."""
    w, x, y, z = np.asarray(q, dtype=float).tolist()
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def rotation_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion with w >= 0 of a rotation matrix (Shepperd's method)."""
    R = R.tolist()
    tr = R[0][0] + R[1][1] + R[2][2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = np.array([0.25 * s, (R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s])
    elif R[0][0] > R[1][1] and R[0][0] > R[2][2]:
        s = 2.0 * math.sqrt(1.0 + R[0][0] - R[1][1] - R[2][2])
        q = np.array([(R[2][1] - R[1][2]) / s, 0.25 * s, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s])
    elif R[1][1] > R[2][2]:
        s = 2.0 * math.sqrt(1.0 + R[1][1] - R[0][0] - R[2][2])
        q = np.array([(R[0][2] - R[2][0]) / s, (R[0][1] + R[1][0]) / s, 0.25 * s, (R[1][2] + R[2][1]) / s])
    else:
        s = 2.0 * math.sqrt(1.0 + R[2][2] - R[0][0] - R[1][1])
        q = np.array([(R[1][0] - R[0][1]) / s, (R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def quat_from_two_vectors(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Shortest rotation taking unit vector u to unit vector v (as PX4's ``Quatf(u, v)``)."""
    c = cross(u, v)
    d = float(np.dot(u, v))
    if d < -1.0 + 1e-6:  # opposite: any axis orthogonal to u
        axis = cross(u, np.array([1.0, 0.0, 0.0])) if abs(u[0]) < 0.9 else cross(u, np.array([0.0, 1.0, 0.0]))
        axis /= np.linalg.norm(axis)
        return np.array([0.0, axis[0], axis[1], axis[2]])
    q = np.array([1.0 + d, c[0], c[1], c[2]])
    return q / np.linalg.norm(q)


def attitude_from_thrust_and_yaw(z_B: np.ndarray, yaw: float) -> np.ndarray:
    """R_WB whose body z is ``z_B`` (unit, world) and whose x axis points along ``yaw`` projected (PX4's
    ``bodyzToAttitude`` in ENU/FLU). Computed in C++, shared with the geometric controller."""
    return _core.control.attitude_from_thrust_and_yaw(z_B, yaw)


def yaw_of(q: np.ndarray) -> float:
    """Heading of body x about world z [rad]."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))

"""Rotations and rigid transforms: every quaternion, rotation-matrix and transform function of cufund, once.

Conventions (as Drake's ``RigidTransform``): a frame pair is written in the name, ``R_AB`` is the rotation matrix
of frame B in frame A (``v_A = R_AB v_B``), ``q_AB`` the same rotation as a quaternion, ``p_A`` a point or vector
in A, ``T_AB`` the rigid transform taking points in B to A (``p_A = R_AB p_B + t_AB``). Quaternions are
[w, x, y, z] (Hamilton, scalar first) at every cufund API; ``q_AB ⊗ q_BC = q_AC``. World ENU, body FLU, SI units.

Functions take one quaternion (4,) / matrix (3, 3) or a batch (…, 4) / (…, 3, 3). The single-element forms run in
plain float arithmetic (they are on per-sample paths); both forms give the same numbers bit for bit. Bad input
(a wrong shape, NaN or inf, a zero quaternion, a matrix that is not a rotation) raises :class:`ValueError` naming
the argument and what was expected.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cufund import _core

__all__ = [
    "PoseFn",
    "Transform",
    "attitude_from_thrust_and_yaw",
    "attitude_from_up_and_yaw",
    "cross",
    "euler_zyx",
    "homogeneous",
    "interpolate_poses",
    "quat_conjugate",
    "quat_from_matrix",
    "quat_from_rotvec",
    "quat_from_two_vectors",
    "quat_mul",
    "quat_to_matrix",
    "sample_poses",
    "unit_quaternion",
    "world_to_body",
    "yaw_of",
    "yaw_quaternion",
]

Array = NDArray[np.float64]

PoseFn = Callable[[float], tuple[object, object]]
"""``pose_fn(t) -> (p_W (3,), q_WB (4,) [w, x, y, z])``: the body pose at time t [s]."""

_MIN_NORM2 = 1e-18
"""A quaternion whose squared norm is below this (norm 1e-9) has no direction: it is refused."""
_UNIT_TOL = 1e-3
"""How far from 1 a quaternion's norm, and from the identity R_AB^T R_AB, may be before it is not a rotation."""


# --- input checks --------------------------------------------------------------------------------------------------


def _floats(value: ArrayLike, field: str, shape: str) -> Array:
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{field} must be an array of numbers of shape {shape}, got {value!r}") from e


def _finite_quaternions(q: ArrayLike, field: str) -> Array:
    """(…, 4) finite float64 quaternions (any norm)."""
    a = _floats(q, field, "(…, 4) [w, x, y, z]")
    if a.ndim == 0 or a.shape[-1] != 4:
        raise ValueError(f"{field} must have shape (4,) or (…, 4) [w, x, y, z], got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{field} must be finite quaternions [w, x, y, z], got NaN or inf in {a!r}")
    return a


def _quaternions(q: ArrayLike, field: str) -> tuple[Array, Array]:
    """(…, 4) finite float64 quaternions with a direction (norm above 1e-9), not normalised, and |q|² (…)."""
    a = _finite_quaternions(q, field)
    norm2 = np.sum(a * a, axis=-1)
    if np.any(norm2 < _MIN_NORM2):
        raise ValueError(f"{field} must be non-zero quaternions [w, x, y, z] (a zero quaternion is no rotation)")
    return a, norm2


def _check_unit(norm2: Array | float, field: str) -> None:
    """|q|² within 2e-3 of 1 (|q| within 1e-3), for one quaternion (a float, no numpy call) or a batch."""
    bad = abs(norm2 - 1.0) > 2 * _UNIT_TOL if isinstance(norm2, float) else np.any(np.abs(norm2 - 1.0) > 2 * _UNIT_TOL)
    if bad:
        raise ValueError(
            f"{field} must be unit quaternions [w, x, y, z] (|q|² = {norm2}); normalise them "
            "(unit_quaternion, or normalize=True)"
        )


def _vectors(v: ArrayLike, field: str) -> Array:
    a = _floats(v, field, "(3,)")
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{field} must be 3 finite numbers, got shape {a.shape} {a!r}")
    return a


def _normalized(q: Array) -> Array:
    """q / |q| over the last axis (one quaternion: numpy's 1-D norm, the dot product's square root)."""
    out: Array = q / (np.linalg.norm(q) if q.ndim == 1 else np.linalg.norm(q, axis=-1, keepdims=True))
    return out


def unit_quaternion(q: ArrayLike, field: str = "q") -> Array:
    """The unit quaternion (4,) [w, x, y, z] in the direction of ``q``; ValueError naming ``field`` if ``q`` is not
    4 finite numbers or is zero."""
    a = _floats(q, field, "(4,) [w, x, y, z]")
    if a.shape != (4,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{field} must be 4 finite numbers [w, x, y, z], got {a.shape} {a!r}")
    if np.linalg.norm(a) < 1e-9:
        raise ValueError(f"{field} must be a non-zero quaternion [w, x, y, z]")
    return _normalized(a)


# --- quaternions and rotation matrices ------------------------------------------------------------------------------


def _matrix_rows(w: Any, x: Any, y: Any, z: Any) -> list[list[Any]]:
    """The rows of R of the unit quaternion [w, x, y, z], for floats or arrays alike (one expression for both)."""
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def quat_to_matrix(q_AB: ArrayLike, normalize: bool = False) -> Array:
    """R_AB (…, 3, 3) of unit quaternions q_AB (…, 4) [w, x, y, z]. With ``normalize`` the quaternions are divided
    by their norm first; without, a norm more than 1e-3 from 1 is refused (the matrix would not be a rotation)."""
    q = _floats(q_AB, "q_AB", "(…, 4) [w, x, y, z]")
    if q.shape == (4,):  # one quaternion in float arithmetic (per-sample paths)
        w, x, y, z = q.tolist()
        n2 = w * w + x * x + y * y + z * z
        if not _MIN_NORM2 <= n2 < math.inf:
            _quaternions(q, "q_AB")  # raises the error that says which
        if normalize:
            w, x, y, z = _normalized(q).tolist()
        else:
            _check_unit(n2, "q_AB")
        return np.array(_matrix_rows(w, x, y, z))
    q, norm2 = _quaternions(q, "q_AB")
    if normalize:
        q = _normalized(q)
    else:
        _check_unit(norm2, "q_AB")
    return np.stack([np.stack(row, -1) for row in _matrix_rows(*np.moveaxis(q, -1, 0))], -2)


def _rotation_matrices(R_AB: ArrayLike) -> Array:
    R = _floats(R_AB, "R_AB", "(…, 3, 3)")
    if R.ndim < 2 or R.shape[-2:] != (3, 3):
        raise ValueError(f"R_AB must have shape (3, 3) or (…, 3, 3), got shape {R.shape}")
    if R.shape == (3, 3):  # one matrix: R_AB^T R_AB - I and the determinant in float arithmetic
        (a, b, c), (d, e, f), (g, h, i) = R.tolist()
        det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
        off = max(
            abs(a * a + d * d + g * g - 1.0),
            abs(b * b + e * e + h * h - 1.0),
            abs(c * c + f * f + i * i - 1.0),
            abs(a * b + d * e + g * h),
            abs(a * c + d * f + g * i),
            abs(b * c + e * f + h * i),
        )
        if off <= _UNIT_TOL and det > 0:  # NaN fails both comparisons
            return R
    if not np.all(np.isfinite(R)):
        raise ValueError(f"R_AB must be finite rotation matrices, got NaN or inf in {R!r}")
    off = float(np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(initial=0.0))
    if off > _UNIT_TOL or np.any(np.linalg.det(R) <= 0):
        raise ValueError(
            f"R_AB must be rotation matrices (orthonormal, determinant +1); |R_AB^T R_AB - I| reaches {off:.3g}"
        )
    return R


def _shepperd(branch: int, m: list[list[Any]], sqrt: Callable[[Any], Any]) -> tuple[Any, Any, Any, Any]:
    """The quaternion [w, x, y, z] (not normalised) of the rotation matrix ``m`` (rows of floats or of arrays) by
    Shepperd's branch 0 (from the trace), 1, 2 or 3 (from R_xx, R_yy, R_zz): one expression for both."""
    if branch == 0:
        s = 2.0 * sqrt(m[0][0] + m[1][1] + m[2][2] + 1.0)
        return 0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s
    if branch == 1:
        s = 2.0 * sqrt(1.0 + m[0][0] - m[1][1] - m[2][2])
        return (m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s
    if branch == 2:
        s = 2.0 * sqrt(1.0 + m[1][1] - m[0][0] - m[2][2])
        return (m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s
    s = 2.0 * sqrt(1.0 + m[2][2] - m[0][0] - m[1][1])
    return (m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s


def quat_from_matrix(R_AB: ArrayLike) -> Array:
    """q_AB (…, 4) [w, x, y, z] with w >= 0 of rotation matrices R_AB (…, 3, 3) (Shepperd's method: the branch
    of the largest of trace, R_xx, R_yy, R_zz, so no division by a small number)."""
    R = _rotation_matrices(R_AB)
    if R.shape == (3, 3):  # one matrix in float arithmetic (per-scan paths)
        m = R.tolist()
        if m[0][0] + m[1][1] + m[2][2] > 0:
            branch = 0
        elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
            branch = 1
        else:
            branch = 2 if m[1][1] > m[2][2] else 3
        out = np.array(_shepperd(branch, m, math.sqrt))
        out /= np.linalg.norm(out)
        return -out if out[0] < 0 else out
    rows = [[R[..., i, j] for j in range(3)] for i in range(3)]
    first = rows[0][0] + rows[1][1] + rows[2][2] > 0
    second = ~first & (rows[0][0] > rows[1][1]) & (rows[0][0] > rows[2][2])
    third = ~first & ~second & (rows[1][1] > rows[2][2])
    # every branch for every matrix (an unused one may take the root of a negative number: silenced, not selected)
    with np.errstate(invalid="ignore", divide="ignore"):
        branches = [np.stack(_shepperd(b, rows, np.sqrt), -1) for b in range(4)]
    out = np.select([first[..., None], second[..., None], third[..., None]], branches[:3], branches[3])
    out = out / np.linalg.norm(out, axis=-1, keepdims=True)
    q_AB: Array = np.where(out[..., :1] < 0, -out, out)
    return q_AB


def _hamilton(a: Any, b: Any) -> list[Any]:
    """a ⊗ b of quaternions given as 4 components [w, x, y, z] each (floats or arrays alike)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]


def quat_mul(q_AB: ArrayLike, q_BC: ArrayLike) -> Array:
    """Hamilton product q_AC = q_AB ⊗ q_BC of (…, 4) quaternions [w, x, y, z] (broadcast against each other)."""
    a = _floats(q_AB, "q_AB", "(…, 4) [w, x, y, z]")
    b = _floats(q_BC, "q_BC", "(…, 4) [w, x, y, z]")
    if a.shape == (4,) and b.shape == (4,):  # one product in float arithmetic
        a_wxyz, b_wxyz = a.tolist(), b.tolist()
        if not math.isfinite(sum(a_wxyz) + sum(b_wxyz)):
            _finite_quaternions(a, "q_AB")
            _finite_quaternions(b, "q_BC")
        return np.array(_hamilton(a_wxyz, b_wxyz))
    a, b = _finite_quaternions(a, "q_AB"), _finite_quaternions(b, "q_BC")
    return np.stack(_hamilton(np.moveaxis(a, -1, 0), np.moveaxis(b, -1, 0)), -1)


def quat_conjugate(q_AB: ArrayLike) -> Array:
    """q_BA (…, 4): the conjugate [w, -x, -y, -z], the inverse rotation of a unit quaternion q_AB."""
    q = _finite_quaternions(q_AB, "q_AB")
    q_BA: Array = q * np.array([1.0, -1.0, -1.0, -1.0])
    return q_BA


def yaw_quaternion(yaw: float) -> Array:
    """q_WB [w, x, y, z] of a rotation by ``yaw`` [rad] about world z."""
    if not math.isfinite(yaw):
        raise ValueError(f"yaw must be a finite angle [rad], got {yaw!r}")
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def _unit_quaternion_floats(q_WB: ArrayLike) -> tuple[float, float, float, float]:
    """One quaternion [w, x, y, z] as four Python floats, checked (shape, finite, non-zero)."""
    q = _floats(q_WB, "q_WB", "(4,) [w, x, y, z]")
    if q.shape != (4,):
        raise ValueError(f"q_WB must have shape (4,) [w, x, y, z], got shape {q.shape}")
    w, x, y, z = q.tolist()
    if not _MIN_NORM2 <= w * w + x * x + y * y + z * z < math.inf:
        _quaternions(q, "q_WB")
    return w, x, y, z


def _yaw(w: float, x: float, y: float, z: float) -> float:
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def yaw_of(q_WB: ArrayLike) -> float:
    """Heading of body x about world z [rad], in (-π, π], of a unit quaternion q_WB [w, x, y, z]."""
    return _yaw(*_unit_quaternion_floats(q_WB))


def euler_zyx(q_WB: ArrayLike) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] of a unit quaternion q_WB [w, x, y, z]: the intrinsic Z-Y-X (Tait-Bryan) angles with
    R_WB = Rz(yaw) Ry(pitch) Rx(roll), as MAVLink's ATTITUDE and scipy's ``as_euler("ZYX")`` (reversed) give them.
    Pitch is in [-π/2, π/2] (its sine clamped to [-1, 1] against rounding); roll and yaw in (-π, π]."""
    w, x, y, z = _unit_quaternion_floats(q_WB)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    return roll, pitch, _yaw(w, x, y, z)


def quat_from_rotvec(phi: ArrayLike) -> Array:
    """The unit quaternion [w, x, y, z] of the rotation vector ``phi`` (3,) [rad] (the exponential map; first order
    below 1e-12 rad)."""
    v = _vectors(phi, "phi")
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        out: Array = np.array([1.0, 0.5 * v[0], 0.5 * v[1], 0.5 * v[2]])
        return out
    s = math.sin(0.5 * angle) / angle
    return np.array([math.cos(0.5 * angle), s * v[0], s * v[1], s * v[2]])


def attitude_from_up_and_yaw(up_B: ArrayLike, yaw: float) -> Array:
    """R_WB of the attitude whose world up axis reads ``up_B`` in the body frame (e.g. a resting IMU's mean specific
    force: it sets roll and pitch) and whose heading is ``yaw`` [rad]: R_WB = Rz(yaw) Ry(pitch) Rx(roll), the
    :func:`euler_zyx` angles, with R_WB^T e_z = up_B / |up_B|."""
    u = _floats(up_B, "up_B", "(3,)")
    n = float(np.linalg.norm(u)) if u.shape == (3,) else 0.0
    if not (n > 0.0 and math.isfinite(n)) or not math.isfinite(yaw):
        raise ValueError(f"up_B must be a finite non-zero 3-vector and yaw a finite angle [rad], got {up_B!r}, {yaw!r}")
    ux, uy, uz = (u / n).tolist()
    pitch = -math.asin(max(-1.0, min(1.0, ux)))
    roll = math.atan2(uy, uz)
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def world_to_body(
    qw: float, qx: float, qy: float, qz: float, x: float, y: float, z: float
) -> tuple[float, float, float]:
    """v_B = R_WB^T v_W for one unit quaternion q_WB [w, x, y, z] and a world vector v_W, in scalar arithmetic (a
    per-sample fast path: the same numbers as ``quat_to_matrix(q_WB).T @ v_W`` up to rounding)."""
    if not math.isfinite(qw + qx + qy + qz + x + y + z):
        raise ValueError(f"world_to_body needs finite numbers, got q_WB {[qw, qx, qy, qz]} v_W {[x, y, z]}")
    return (
        (1 - 2 * (qy * qy + qz * qz)) * x + 2 * (qx * qy + qw * qz) * y + 2 * (qx * qz - qw * qy) * z,
        2 * (qx * qy - qw * qz) * x + (1 - 2 * (qx * qx + qz * qz)) * y + 2 * (qy * qz + qw * qx) * z,
        2 * (qx * qz + qw * qy) * x + 2 * (qy * qz - qw * qx) * y + (1 - 2 * (qx * qx + qy * qy)) * z,
    )


def cross(a: ArrayLike, b: ArrayLike) -> Array:
    """a × b of two 3-vectors in the same frame (np.cross is slow for single vectors)."""
    a0, a1, a2 = _vectors(a, "a").tolist()
    b0, b1, b2 = _vectors(b, "b").tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def quat_from_two_vectors(u_A: ArrayLike, v_A: ArrayLike) -> Array:
    """The shortest rotation q [w, x, y, z] taking unit vector u_A to unit vector v_A (both in frame A), as PX4's
    ``Quatf(u, v)``; for opposite vectors a half turn about an axis orthogonal to u_A."""
    u, v = _vectors(u_A, "u_A"), _vectors(v_A, "v_A")
    c = cross(u, v)
    d = float(np.dot(u, v))
    if d < -1.0 + 1e-6:  # opposite: any axis orthogonal to u
        axis = cross(u, np.array([1.0, 0.0, 0.0])) if abs(u[0]) < 0.9 else cross(u, np.array([0.0, 1.0, 0.0]))
        axis /= np.linalg.norm(axis)
        return np.array([0.0, axis[0], axis[1], axis[2]])
    q = np.array([1.0 + d, c[0], c[1], c[2]])
    n = np.linalg.norm(q)
    if not n > 1e-9:
        raise ValueError(f"u_A and v_A must be unit vectors, got {u!r} and {v!r}")
    out: Array = q / n
    return out


def attitude_from_thrust_and_yaw(z_B: ArrayLike, yaw: float) -> Array:
    """R_WB whose body z axis is ``z_B`` (a unit vector in world coordinates) and whose x axis points along
    ``yaw`` [rad] projected (PX4's ``bodyzToAttitude`` in ENU/FLU). Computed in C++, shared with the geometric
    controller."""
    out: Array = _core.control.attitude_from_thrust_and_yaw(z_B, yaw)
    return out


# --- rigid transforms ---------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Transform:
    """Rigid transform T_AB: maps points from frame B to frame A (p_A = R_AB p_B + t_AB). ``T_AC = T_AB @ T_BC``."""

    t: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Translation t_AB, origin of B in A [m]."""
    q: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Rotation q_AB [w, x, y, z] (normalised on construction)."""

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"t must be 3 finite numbers [m], got {self.t!r}")
        object.__setattr__(self, "t", tuple(float(v) for v in t))
        object.__setattr__(self, "q", tuple(float(v) for v in unit_quaternion(self.q, "q")))

    @property
    def R(self) -> Array:
        """R_AB (3, 3)."""
        return quat_to_matrix(np.array(self.q))

    def inverse(self) -> Transform:
        """T_BA: p_B = R_AB^T (p_A - t_AB)."""
        q_BA = quat_conjugate(np.array(self.q))
        t_BA = -(self.R.T @ np.array(self.t))
        return Transform(
            (float(t_BA[0]), float(t_BA[1]), float(t_BA[2])),
            (float(q_BA[0]), float(q_BA[1]), float(q_BA[2]), float(q_BA[3])),
        )

    def __matmul__(self, other: Transform) -> Transform:
        """T_AC = T_AB @ T_BC."""
        if not isinstance(other, Transform):
            return NotImplemented
        t_AC = np.array(self.t) + self.R @ np.array(other.t)
        q_AC = quat_mul(np.array(self.q), np.array(other.q))
        return Transform(
            (float(t_AC[0]), float(t_AC[1]), float(t_AC[2])),
            (float(q_AC[0]), float(q_AC[1]), float(q_AC[2]), float(q_AC[3])),
        )


def homogeneous(T_AB: Transform) -> Array:
    """The 4x4 homogeneous matrix [[R_AB, t_AB], [0, 1]] of a Transform T_AB (B -> A)."""
    if not isinstance(T_AB, Transform):
        raise TypeError(f"T_AB must be a cufund.geometry.Transform, got {type(T_AB).__name__}")
    M = np.eye(4)
    M[:3, :3] = quat_to_matrix(np.asarray(T_AB.q), normalize=True)
    M[:3, 3] = T_AB.t
    return M


# --- pose trajectories --------------------------------------------------------------------------------------------


def sample_poses(pose_fn: PoseFn, times: Array, T_BS: Transform) -> tuple[Array, Array]:
    """Sensor poses at ``times``: p_WS (K, 3) and q_WS (K, 4), from the body poses pose_fn(t) composed with the
    mounting T_BS. Quaternion signs are aligned so interpolation takes the short way."""
    p_WB = np.empty((len(times), 3))
    q_WB = np.empty((len(times), 4))
    for k, t in enumerate(times):
        p, q = pose_fn(float(t))
        p = np.asarray(p, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"pose_fn({t}) must return p_W as 3 finite numbers [m], got {p!r}")
        p_WB[k] = p
        q_WB[k] = unit_quaternion(q, f"pose_fn({t}) q_WB")  # type: ignore[arg-type]
        if k and np.dot(q_WB[k], q_WB[k - 1]) < 0:
            q_WB[k] = -q_WB[k]
    q_WS = quat_mul(q_WB, np.array(T_BS.q))
    p_WS = p_WB + quat_to_matrix(q_WB) @ np.array(T_BS.t)
    return p_WS, q_WS


def interpolate_poses(t_knots: ArrayLike, p_knots: ArrayLike, q_knots: ArrayLike, t: ArrayLike) -> tuple[Array, Array]:
    """Body positions p_W (N, 3) and rotations R_WB (N, 3, 3) at times ``t`` [s] from pose knots (stamps (K,)
    ascending, positions (K, 3), quaternions q_WB (K, 4) [w, x, y, z]): linear in position, normalised linear in the
    quaternion (short way round), clamped at the ends."""
    ts, p, q = np.asarray(t_knots), np.asarray(p_knots), np.asarray(q_knots)
    t = np.asarray(t)
    if len(ts) == 0 or p.shape != (len(ts), 3) or q.shape != (len(ts), 4):
        raise ValueError(
            f"pose knots must be stamps (K,) with K >= 1, p_knots (K, 3) and q_knots (K, 4), got "
            f"{ts.shape}, {p.shape}, {q.shape}"
        )
    if len(ts) == 1:
        return np.repeat(p, len(t), axis=0), np.repeat(quat_to_matrix(q), len(t), axis=0)
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    s = np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0)[:, None]
    q0, q1 = q[i], q[i + 1]
    q1 = np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -q1, q1)
    qs = (1 - s) * q0 + s * q1
    return (1 - s) * p[i] + s * p[i + 1], quat_to_matrix(_normalized(qs))


# --- names of cufund 0.1 that were duplicates ---------------------------------------------------------------------


def _matrix_from_quat(q_AB: ArrayLike) -> Array:
    return quat_to_matrix(q_AB, normalize=True)


_DEPRECATED: dict[str, tuple[str, Callable[..., Any]]] = {
    "quat_multiply": ("quat_mul", quat_mul),
    "quat_to_rotation": ("quat_to_matrix", quat_to_matrix),
    "rotation_to_quat": ("quat_from_matrix", quat_from_matrix),
    "matrix_from_quat": ("quat_to_matrix(q, normalize=True)", _matrix_from_quat),
}
"""0.1's second names for the same function (in cufund.control.rotations and cufund.estimation.frames) -> the one
name here; they import with a DeprecationWarning and go in the next release."""


def __getattr__(name: str) -> Any:
    if name in _DEPRECATED:
        new, fn = _DEPRECATED[name]
        warnings.warn(
            f"cufund.geometry.{name} is {new}; the old name goes in the next release", DeprecationWarning, stacklevel=2
        )
        return fn
    raise AttributeError(f"module 'cufund.geometry' has no attribute {name!r}")

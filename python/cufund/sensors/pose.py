"""Poses for sensors: quaternions [w, x, y, z], rigid transforms and pose trajectories sampled in time."""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

PoseFn = Callable[[float], tuple[object, object]]
"""``pose_fn(t) -> (p_W (3,), q_WB (4,) [w, x, y, z])``: the body pose at time t [s]."""


def _unit_quaternion(q: object, field: str) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    if q.shape != (4,) or not np.all(np.isfinite(q)):
        raise ValueError(f"{field} must be 4 finite numbers [w, x, y, z], got {q.shape} {q!r}")
    n = np.linalg.norm(q)
    if n < 1e-9:
        raise ValueError(f"{field} must be a non-zero quaternion [w, x, y, z]")
    return q / n


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(…, 4) unit quaternions [w, x, y, z] -> (…, 3, 3) rotation matrices."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def world_to_body(qw: float, qx: float, qy: float, qz: float, x: float, y: float, z: float
                  ) -> tuple[float, float, float]:
    """R_WB^T v for one unit quaternion q_WB [w, x, y, z] and world vector v, in scalar arithmetic (a
    per-sample fast path: the same numbers as ``quat_to_matrix(q).T @ v`` up to rounding)."""
    return ((1 - 2 * (qy * qy + qz * qz)) * x + 2 * (qx * qy + qw * qz) * y + 2 * (qx * qz - qw * qy) * z,
            2 * (qx * qy - qw * qz) * x + (1 - 2 * (qx * qx + qz * qz)) * y + 2 * (qy * qz + qw * qx) * z,
            2 * (qx * qz + qw * qy) * x + 2 * (qy * qz - qw * qx) * y + (1 - 2 * (qx * qx + qy * qy)) * z)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of (…, 4) quaternions [w, x, y, z]."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], -1)


def yaw_quaternion(yaw: float) -> np.ndarray:
    """[w, x, y, z] of a rotation by ``yaw`` [rad] about z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


@dataclasses.dataclass(frozen=True)
class Transform:
    """Rigid transform T_AB: maps points from frame B to frame A (p_A = R_AB p_B + t_AB)."""

    t: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Translation t_AB, origin of B in A [m]."""
    q: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Rotation q_AB [w, x, y, z]."""

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"t must be 3 finite numbers [m], got {self.t!r}")
        object.__setattr__(self, "t", tuple(float(v) for v in t))
        object.__setattr__(self, "q", tuple(float(v) for v in _unit_quaternion(self.q, "q")))

    @property
    def R(self) -> np.ndarray:
        return quat_to_matrix(np.array(self.q))


def sample_poses(pose_fn: PoseFn, times: np.ndarray, T_BS: Transform) -> tuple[np.ndarray, np.ndarray]:
    """Sensor poses at ``times``: p_WS (K, 3) and R_WS (K, 3, 3), from the body poses pose_fn(t)
    composed with the mounting T_BS. Quaternion signs are aligned so interpolation takes the short way."""
    p_WB = np.empty((len(times), 3))
    q_WB = np.empty((len(times), 4))
    for k, t in enumerate(times):
        p, q = pose_fn(float(t))
        p = np.asarray(p, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"pose_fn({t}) must return p_W as 3 finite numbers [m], got {p!r}")
        p_WB[k] = p
        q_WB[k] = _unit_quaternion(q, f"pose_fn({t}) q_WB")
        if k and np.dot(q_WB[k], q_WB[k - 1]) < 0:
            q_WB[k] = -q_WB[k]
    q_WS = quat_mul(q_WB, np.array(T_BS.q))
    p_WS = p_WB + quat_to_matrix(q_WB) @ np.array(T_BS.t)
    return p_WS, q_WS


def interpolate_poses(t_knots: np.ndarray, p_knots: np.ndarray, q_knots: np.ndarray,
                      t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body positions (N, 3) and rotations (N, 3, 3) at times ``t`` [s] from pose knots (stamps (K,) ascending,
    positions (K, 3), quaternions (K, 4) [w, x, y, z]): linear in position, normalised linear in the quaternion
    (short way round), clamped at the ends."""
    ts, p, q = np.asarray(t_knots), np.asarray(p_knots), np.asarray(q_knots)
    if len(ts) == 1:
        return np.repeat(p, len(t), axis=0), np.repeat(quat_to_matrix(q), len(t), axis=0)
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    s = np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0)[:, None]
    q0, q1 = q[i], q[i + 1]
    q1 = np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -q1, q1)
    qs = (1 - s) * q0 + s * q1
    return (1 - s) * p[i] + s * p[i + 1], quat_to_matrix(qs / np.linalg.norm(qs, axis=1, keepdims=True))

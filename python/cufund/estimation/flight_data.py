"""Offline LiDAR-inertial flight records from the standalone sensor models (no simulator needed).

A smooth trajectory (e.g. :class:`cufund.planning.MinimumSnapTrajectory`) gives position and yaw; the attitude
follows a quadrotor's differential flatness (thrust axis along a_W + g e_z), body rates and angular
accelerations are central differences of that attitude. The IMU (:class:`cufund.sensors.ImuModel`) and the
LiDAR (:class:`cufund.sensors.Lidar`) then sample that motion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.geometry import quat_from_matrix
from cufund.sensors.imu import G0, ImuModel

from .boundary import scan_frame

__all__ = ["FlightRecord", "LidarFrame", "FlatBodyMotion", "record_flight", "replay"]


@dataclass(frozen=True)
class LidarFrame:
    t: float
    """Frame start [s]."""
    dt: np.ndarray
    """(N,) per-point offsets from t [s]."""
    points_L: np.ndarray
    """(N, 3) float32 points in the LiDAR frame at their own firing times [m]."""


@dataclass(frozen=True)
class FlightRecord:
    t_imu: np.ndarray
    """(K,) IMU sample times [s]."""
    acc_I: np.ndarray
    """(K, 3) accelerometer [m/s^2]."""
    gyr_I: np.ndarray
    """(K, 3) gyroscope [rad/s]."""
    frames: list[LidarFrame]
    motion: FlatBodyMotion
    """The true body motion (truth for evaluation)."""


class FlatBodyMotion:
    """Body pose, velocity, rates and accelerations of a quadrotor flying ``trajectory``'s position and yaw."""

    def __init__(self, trajectory: Any, gravity: float = G0, h: float = 1e-4) -> None:
        self.trajectory = trajectory
        self.gravity = float(gravity)
        self.h = float(h)

    def _R(self, t: np.ndarray) -> np.ndarray:
        s = self.trajectory.sample(np.atleast_1d(np.asarray(t, dtype=float)))
        z = s.a_W + np.array([0.0, 0.0, self.gravity])
        z /= np.linalg.norm(z, axis=1, keepdims=True)
        x_c = np.stack([np.cos(s.yaw), np.sin(s.yaw), np.zeros_like(s.yaw)], axis=1)
        y = np.cross(z, x_c)
        y /= np.linalg.norm(y, axis=1, keepdims=True)
        x = np.cross(y, z)
        return np.stack([x, y, z], axis=2)

    def _w(self, t: np.ndarray) -> np.ndarray:
        Rm, Rp, R0 = self._R(t - self.h), self._R(t + self.h), self._R(t)
        S = np.einsum("kji,kjl->kil", R0, (Rp - Rm) / (2 * self.h))  # R^T dR/dt
        return np.stack([S[:, 2, 1] - S[:, 1, 2], S[:, 0, 2] - S[:, 2, 0], S[:, 1, 0] - S[:, 0, 1]], axis=1) / 2

    def state(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """p_W, v_W, a_W (K, 3), q_WB (K, 4) [w, x, y, z], R_WB (K, 3, 3), w_B, alpha_B (K, 3) at times t (K,)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        s = self.trajectory.sample(t)
        R = self._R(t)
        alpha = (self._w(t + self.h) - self._w(t - self.h)) / (2 * self.h)
        return {
            "p_W": s.p_W,
            "v_W": s.v_W,
            "a_W": s.a_W,
            "R_WB": R,
            "q_WB": quat_from_matrix(R),
            "w_B": self._w(t),
            "alpha_B": alpha,
        }

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """pose_fn(t) -> (p_W, q_WB) for :meth:`cufund.sensors.Lidar.scan`."""
        st = self.state(np.array([t]))
        return st["p_W"][0], st["q_WB"][0]


def record_flight(
    motion: FlatBodyMotion, imu: ImuModel, lidar: Any, world: Any, t_start: float, t_end: float
) -> FlightRecord:
    """IMU samples at the IMU's rate and consecutive LiDAR frames over [t_start, t_end)."""
    rate = imu.params.rate_hz
    t_imu = t_start + np.arange(int(np.floor((t_end - t_start) * rate))) / rate
    st = motion.state(t_imu)
    acc, gyr = imu.measure(st["q_WB"], st["w_B"], st["a_W"], st["alpha_B"])
    frames = []
    t = t_start
    while t + lidar.period <= t_end + 1e-9:
        cloud = lidar.scan(world, motion.pose, t)
        t0, dt, pts = scan_frame(cloud)
        frames.append(LidarFrame(t0, dt, np.asarray(pts, dtype=np.float32)))
        t += lidar.period
    return FlightRecord(t_imu, acc, gyr, frames, motion)


def replay(core: Any, record: FlightRecord) -> tuple[list[Any], list[Any]]:
    """Feeds a record to a :class:`LioCore` in time order (each frame after the IMU samples up to its end).
    Returns (odometry at each frame end, odometry at each IMU sample)."""
    at_scans, at_imu = [], []
    j = 0
    n = len(record.t_imu)
    for f in record.frames:
        t_end = f.t + (float(f.dt.max()) if len(f.dt) else 0.0)
        while j < n and record.t_imu[j] <= t_end:
            o = core.add_imu(record.t_imu[j], record.acc_I[j], record.gyr_I[j])
            if o is not None:
                at_imu.append(o)
            j += 1
        o = core.add_scan(f.t, f.dt, f.points_L)
        if o is not None:
            at_scans.append(o)
    return at_scans, at_imu

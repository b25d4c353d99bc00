"""An IMU propagator: IMU-rate odometry between slow pose corrections (motion capture, a 10 Hz odometry).

Between corrections it integrates every IMU sample (specific force rotated to the world, gravity added; body
rate from the gyro); when a correction stamped t_c arrives (possibly late), it resets the state to the
corrected pose and velocity at t_c and re-integrates the buffered samples after t_c, so a delayed correction is
applied where it belongs. Accelerometer and gyro biases are estimated from the corrections (a first-order
complementary filter on the velocity and attitude innovations). The IMU is taken at the centre of mass: a
lever arm ``p_BI`` is ignored (documented limit).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from cufund.core.bus import BusView, Subscription
from cufund.core.components import Estimator
from cufund.core.config import check_at_most, check_real_fields
from cufund.core.messages import Imu, Odometry, Topics
from cufund.geometry import quat_mul, quat_to_matrix

__all__ = ["ImuPropagator", "ImuPropagatorParams"]


@dataclass(frozen=True)
class ImuPropagatorParams:
    """Gains of the bias estimates (0 disables them) and how long IMU samples are kept for late corrections."""

    accel_bias_gain: float = 0.2
    """Fraction of the velocity innovation per correction interval attributed to accelerometer bias."""
    gyro_bias_gain: float = 0.2
    """Fraction of the attitude innovation per correction interval attributed to gyro bias."""
    buffer_s: float = 1.0
    """IMU history kept for re-integration after a late correction [s]."""

    def __post_init__(self) -> None:
        check_real_fields(self, "estimator")
        check_at_most(self, "estimator", buffer_s=60.0)  # IMU samples kept: at most 60 s of them


def _exp_q(phi: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(phi))
    if angle < 1e-12:
        return np.array([1.0, 0.5 * phi[0], 0.5 * phi[1], 0.5 * phi[2]])
    s = math.sin(0.5 * angle) / angle
    return np.array([math.cos(0.5 * angle), s * phi[0], s * phi[1], s * phi[2]])


class ImuPropagator(Estimator):
    """Publishes :class:`Odometry` on ``Topics.ESTIMATE`` at ``rate_hz`` (the IMU's rate: one output per sample)
    from every IMU sample on ``imu_topic`` and the corrections on ``pose_topic``."""

    name = "imu_propagator"

    def __init__(
        self,
        rate_hz: float,
        gravity: float,
        q_BI: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
        params: ImuPropagatorParams | None = None,
        imu_topic: str = Topics.IMU,
        pose_topic: str = Topics.POSE,
    ) -> None:
        self.rate_hz, self.gravity = float(rate_hz), float(gravity)
        self.params = params or ImuPropagatorParams()
        self.R_BI = quat_to_matrix(np.asarray(q_BI, dtype=float))
        self.imu_topic, self.pose_topic = imu_topic, pose_topic
        self.inputs = (imu_topic, pose_topic)
        self.reset()

    def reset(self) -> None:
        self._samples: deque[tuple[float, np.ndarray, np.ndarray]] = deque()
        self._x: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None  # t, p, v, q
        self._w_B = np.zeros(3)
        self.b_a = np.zeros(3)
        """Accelerometer bias estimate, body frame [m/s^2]."""
        self.b_g = np.zeros(3)
        """Gyro bias estimate, body frame [rad/s]."""
        self._last_fix: Odometry | None = None

    def setup(self, bus: BusView) -> None:
        self._imu: Subscription = bus.subscribe(self.imu_topic)
        self._pose: Subscription = bus.subscribe(self.pose_topic)

    def _propagate(self, x: tuple, t1: float, f_B: np.ndarray, w_B: np.ndarray) -> tuple:
        t0, p, v, q = x
        dt = t1 - t0
        if dt <= 0:
            return x
        R = quat_to_matrix(q)
        a = R @ (f_B - self.b_a) - np.array([0.0, 0.0, self.gravity])
        q1 = quat_mul(q, _exp_q((w_B - self.b_g) * dt))
        return (t1, p + v * dt + 0.5 * a * dt * dt, v + a * dt, q1 / np.linalg.norm(q1))

    def _correct(self, fix: Odometry) -> None:
        """Resets the state at the fix's stamp and re-integrates the samples after it."""
        g = self.params
        prev = self._last_fix
        if self._x is not None and prev is not None and fix.t > prev.t:
            # innovation against the state the last fix and the samples since predict at this fix's time
            pred = self._state_at(fix.t)
            if pred is not None:
                T = fix.t - prev.t
                dv = np.asarray(fix.v_W) - pred[2]
                R = quat_to_matrix(pred[3])
                self.b_a = self.b_a - g.accel_bias_gain * (R.T @ dv) / T
                dq = quat_mul(np.r_[pred[3][0], -pred[3][1:]], np.asarray(fix.q_WB))
                if dq[0] < 0:
                    dq = -dq
                self.b_g = self.b_g - g.gyro_bias_gain * 2.0 * dq[1:] / T
        self._last_fix = fix
        x = (
            fix.t,
            np.asarray(fix.p_W, dtype=float),
            np.asarray(fix.v_W, dtype=float),
            np.asarray(fix.q_WB, dtype=float),
        )
        for t, f, w in self._samples:
            if t > fix.t:
                x = self._propagate(x, t, f, w)
        self._x = x

    def _state_at(self, t_fix: float) -> tuple | None:
        """The state the previous correction and the samples up to ``t_fix`` predict there."""
        prev = self._last_fix
        if prev is None:
            return None
        x = (
            prev.t,
            np.asarray(prev.p_W, dtype=float),
            np.asarray(prev.v_W, dtype=float),
            np.asarray(prev.q_WB, dtype=float),
        )
        for t, f, w in self._samples:
            if prev.t < t <= t_fix:
                x = self._propagate(x, t, f, w)
        return x

    def estimate(self, t: float, bus: BusView) -> Odometry | None:
        new = self._imu.take()
        m: Imu
        for m in new:
            f_B, w_B = self.R_BI @ m.f_I, self.R_BI @ m.w_I
            self._samples.append((m.t, f_B, w_B))
            self._w_B = w_B
            if self._x is not None:
                self._x = self._propagate(self._x, m.t, f_B, w_B)
        for fix in self._pose.take():
            self._correct(fix)
        horizon = t - self.params.buffer_s
        while self._samples and self._samples[0][0] < horizon:
            self._samples.popleft()
        if self._x is None:
            return None
        t_x, p, v, q = self._x
        return Odometry(t_x, p.copy(), v.copy(), q.copy(), self._w_B - self.b_g)

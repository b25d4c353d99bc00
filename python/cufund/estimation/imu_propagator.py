"""An IMU propagator: IMU-rate odometry corrected by a pose source (motion capture, a slow odometry).

An error-state Kalman filter (Solà, "Quaternion kinematics for the error-state Kalman filter", arXiv:1711.02508,
§5-7) on the nominal state ``[p_W, v_W, q_WB, b_a, b_g]`` with the 15-dimensional error
``[dp, dv, dtheta (body frame, q = q_hat * Exp(dtheta)), db_a, db_g]``:

- every IMU sample propagates the nominal state (specific force rotated to the world, gravity added; the gyro's
  rate for the attitude; both less their bias estimates) and the error covariance (first-order discrete
  transition, process noise from the IMU's noise densities and bias random walks);
- every :class:`~cufund.core.messages.Pose` (position and attitude only: motion capture measures no velocity)
  corrects position and attitude; velocity and both biases are corrected through their covariance with them
  (velocity from how the position innovations move, the accelerometer bias from how they accelerate, the
  gyro bias from the attitude innovations), then the error is injected and reset.

Delayed corrections: the filter keeps each IMU sample with the state and covariance after it for
``params.buffer_s``; a pose stamped ``t_c`` (arriving its source's latency later) is applied to the state at
``t_c``, then the samples after ``t_c`` are integrated again (state and covariance), so it acts where it belongs.

Nothing is known before the first pose: the filter starts there (its position and attitude, zero velocity and
biases with the prior sigmas of :class:`ImuPropagatorParams`) and publishes nothing before. No truth is read.

Each estimate carries its covariances (``Odometry.pose_cov_W``, ``twist_cov_B``): the error covariance mapped to
first order to ROS's ``nav_msgs/Odometry`` frames and order (the attitude error about the world axes, the velocity in
the body), the rate's including the gyro's white noise on its one sample.
The IMU is taken at the centre of mass: a lever arm ``p_BI`` is ignored (documented limit).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from cufund.core.bus import BusView, Subscription
from cufund.core.components import Estimator
from cufund.core.config import check_at_most, check_real_fields
from cufund.core.messages import Imu, Odometry, Pose, Topics
from cufund.geometry import quat_from_rotvec, quat_mul, quat_to_matrix

__all__ = ["ImuPropagator", "ImuPropagatorParams"]


@dataclass(frozen=True)
class ImuPropagatorParams:
    """The filter's noise model (its own tuning: what flight software is told about its sensors, never the
    simulated ones' values), its priors, and how long IMU samples are kept for late corrections. Defaults: a
    TDK ICM-42688-P class IMU (densities inflated about 3x for vibration and unmodelled errors) and motion
    capture of about 0.5 mm and 0.1 deg."""

    accel_noise_density: float = 2e-3
    """Accelerometer white noise [m/s^2/sqrt(Hz)] (ICM-42688-P datasheet: 70 ug/sqrt(Hz) = 6.9e-4)."""
    gyro_noise_density: float = 1.5e-4
    """Gyro white noise [rad/s/sqrt(Hz)] (ICM-42688-P datasheet: 0.0028 deg/s/sqrt(Hz) = 4.9e-5)."""
    accel_bias_random_walk: float = 1e-3
    """Accelerometer bias random walk [m/s^3/sqrt(Hz)]."""
    gyro_bias_random_walk: float = 5e-5
    """Gyro bias random walk [rad/s^2/sqrt(Hz)]."""
    position_sigma_m: float = 5e-4
    """Noise of the pose source's position, per axis [m]."""
    attitude_sigma_rad: float = 1.75e-3
    """Noise of the pose source's attitude, per axis [rad] (0.1 deg)."""
    velocity_prior_m_s: float = 0.1
    """Sigma of the initial velocity (zero) [m/s]."""
    accel_bias_prior: float = 0.2
    """Sigma of the initial accelerometer bias (zero) [m/s^2] (the datasheet's 20 mg zero-g offset)."""
    gyro_bias_prior: float = 0.01
    """Sigma of the initial gyro bias (zero) [rad/s] (the datasheet's 0.5 deg/s zero-rate offset)."""
    buffer_s: float = 1.0
    """IMU history kept for re-integration after a late correction [s]."""

    def __post_init__(self) -> None:
        check_real_fields(self, "estimator")
        for name in ("position_sigma_m", "attitude_sigma_rad"):
            if getattr(self, name) == 0:
                raise ValueError(f"estimator.{name} must be > 0 (the pose source's noise), got 0")
        check_at_most(self, "estimator", buffer_s=60.0)  # IMU samples kept: at most 60 s of them


def _log_q(q: np.ndarray) -> np.ndarray:
    """The rotation vector [rad] of the unit quaternion ``q`` (the shorter way round)."""
    if q[0] < 0:
        q = -q
    n = float(np.linalg.norm(q[1:]))
    if n < 1e-12:
        return 2.0 * q[1:]
    return (2.0 * math.atan2(n, q[0]) / n) * q[1:]


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


class _State:
    """Nominal state and error covariance at ``t`` (after the IMU sample stamped ``t``)."""

    __slots__ = ("t", "p", "v", "q", "b_a", "b_g", "P")

    def __init__(
        self, t: float, p: np.ndarray, v: np.ndarray, q: np.ndarray, b_a: np.ndarray, b_g: np.ndarray, P: np.ndarray
    ) -> None:
        self.t, self.p, self.v, self.q, self.b_a, self.b_g, self.P = t, p, v, q, b_a, b_g, P


_H = np.zeros((6, 15))
_H[0:3, 0:3] = np.eye(3)
_H[3:6, 6:9] = np.eye(3)


class ImuPropagator(Estimator):
    """Publishes :class:`Odometry` on ``Topics.ESTIMATE`` at ``rate_hz`` (the IMU's rate: one output per sample)
    from every IMU sample on ``imu_topic`` and the :class:`Pose` corrections on ``pose_topic`` (see the module
    docstring)."""

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
        self.params = g = params or ImuPropagatorParams()
        self.R_BI = quat_to_matrix(np.asarray(q_BI, dtype=float))
        self.imu_topic, self.pose_topic = imu_topic, pose_topic
        self.inputs = (imu_topic, pose_topic)
        self._g_W = np.array([0.0, 0.0, self.gravity])
        self._R_meas = np.diag([g.position_sigma_m**2] * 3 + [g.attitude_sigma_rad**2] * 3)
        self._q_rates = np.array(
            [g.accel_noise_density**2] * 3
            + [g.gyro_noise_density**2] * 3
            + [g.accel_bias_random_walk**2] * 3
            + [g.gyro_bias_random_walk**2] * 3
        )  # continuous-time noise PSDs of v, theta, b_a, b_g
        self.reset()

    def reset(self) -> None:
        self._history: deque[tuple[float, np.ndarray, np.ndarray, _State | None]] = deque()
        """(t, f_B, w_B, state after the sample or None before the first pose), oldest first."""
        self._x: _State | None = None
        self._w_B = np.zeros(3)
        self.corrections = 0
        """Poses applied so far."""
        self.late_corrections = 0
        """Poses older than the kept IMU history (applied to the oldest state kept)."""

    @property
    def b_a(self) -> np.ndarray:
        """Accelerometer bias estimate, body frame [m/s^2] (zero before the first pose)."""
        return self._x.b_a.copy() if self._x is not None else np.zeros(3)

    @property
    def b_g(self) -> np.ndarray:
        """Gyro bias estimate, body frame [rad/s] (zero before the first pose)."""
        return self._x.b_g.copy() if self._x is not None else np.zeros(3)

    @property
    def covariance(self) -> np.ndarray | None:
        """The error covariance (15 x 15, order dp, dv, dtheta, db_a, db_g), or None before the first pose."""
        return self._x.P.copy() if self._x is not None else None

    def setup(self, bus: BusView) -> None:
        self._imu: Subscription = bus.subscribe(self.imu_topic)
        self._pose: Subscription = bus.subscribe(self.pose_topic)

    # ---- filter ------------------------------------------------------------------------------------------------
    def _propagate(self, x: _State, t1: float, f_B: np.ndarray, w_B: np.ndarray) -> _State:
        dt = t1 - x.t
        if dt <= 0:
            return x
        R = quat_to_matrix(x.q)
        f = f_B - x.b_a
        w = w_B - x.b_g
        a = R @ f - self._g_W
        q1 = quat_mul(x.q, quat_from_rotvec(w * dt))
        F = np.eye(15)
        F[0:3, 3:6] = dt * np.eye(3)
        F[3:6, 6:9] = -dt * (R @ _skew(f))
        F[3:6, 9:12] = -dt * R
        F[6:9, 6:9] = quat_to_matrix(quat_from_rotvec(w * dt)).T
        F[6:9, 12:15] = -dt * np.eye(3)
        P = F @ x.P @ F.T
        P[np.arange(3, 15), np.arange(3, 15)] += self._q_rates * dt
        return _State(
            t1, x.p + x.v * dt + 0.5 * a * dt * dt, x.v + a * dt, q1 / np.linalg.norm(q1), x.b_a, x.b_g, 0.5 * (P + P.T)
        )

    def _update(self, x: _State, z: Pose) -> _State:
        """The state corrected by the pose ``z`` (stamped at ``x.t``)."""
        r = np.empty(6)
        r[0:3] = np.asarray(z.p_W, dtype=float) - x.p
        r[3:6] = _log_q(quat_mul(np.r_[x.q[0], -x.q[1:]], np.asarray(z.q_WB, dtype=float)))
        P = x.P
        S = P[np.ix_([0, 1, 2, 6, 7, 8], [0, 1, 2, 6, 7, 8])] + self._R_meas
        PHt = P[:, [0, 1, 2, 6, 7, 8]]
        K = np.linalg.solve(S, PHt.T).T
        dx = K @ r
        IKH = np.eye(15) - K @ _H
        P = IKH @ P @ IKH.T + K @ self._R_meas @ K.T
        q = quat_mul(x.q, quat_from_rotvec(dx[6:9]))
        return _State(x.t, x.p + dx[0:3], x.v + dx[3:6], q / np.linalg.norm(q), x.b_a + dx[9:12], x.b_g + dx[12:15], P)

    def _initial(self, z: Pose) -> _State:
        g = self.params
        P = np.diag(
            [g.position_sigma_m**2] * 3
            + [g.velocity_prior_m_s**2] * 3
            + [g.attitude_sigma_rad**2] * 3
            + [g.accel_bias_prior**2] * 3
            + [g.gyro_bias_prior**2] * 3
        )
        q = np.asarray(z.q_WB, dtype=float)
        return _State(
            float(z.t), np.asarray(z.p_W, dtype=float).copy(), np.zeros(3), q / np.linalg.norm(q), np.zeros(3),
            np.zeros(3), P,
        )  # fmt: skip

    def _correct(self, z: Pose) -> None:
        """Applies the pose ``z`` at its stamp and integrates the samples after it again."""
        hist = self._history
        t_c = float(z.t)
        # the newest kept state at or before t_c, and the index of the first sample after t_c
        k = len(hist)
        while k > 0 and hist[k - 1][0] > t_c:
            k -= 1
        base = hist[k - 1][3] if k > 0 else None
        if self._x is None or base is None:
            if self._x is not None:  # older than everything kept: apply it to the oldest state (and count it)
                self.late_corrections += 1
                i = next((i for i, h in enumerate(hist) if h[3] is not None), None)
                oldest, k = (self._x, len(hist)) if i is None else (hist[i][3] or self._x, i + 1)
                x = self._update(oldest, Pose(oldest.t, z.p_W, z.q_WB))
            else:
                x = self._initial(z)
        else:
            x = base
            if k < len(hist) and t_c > x.t:  # up to t_c on the next sample's reading
                x = self._propagate(x, t_c, hist[k][1], hist[k][2])
            x = self._update(x, z)
        for i in range(k, len(hist)):
            t, f, w, _ = hist[i]
            x = self._propagate(x, t, f, w)
            hist[i] = (t, f, w, x)
        self._x = x
        self.corrections += 1

    def estimate(self, t: float, bus: BusView) -> Odometry | None:
        m: Imu
        for m in self._imu.take():
            f_B, w_B = self.R_BI @ m.f_I, self.R_BI @ m.w_I
            self._w_B = w_B
            if self._x is not None:
                self._x = self._propagate(self._x, m.t, f_B, w_B)
            self._history.append((m.t, f_B, w_B, self._x))
        for z in self._pose.take():
            self._correct(z)
        horizon = t - self.params.buffer_s
        while len(self._history) > 1 and self._history[0][0] < horizon:
            self._history.popleft()
        x = self._x
        if x is None:
            return None
        w_B = self._w_B - x.b_g
        pose_cov, twist_cov = self._output_covariances(x)
        return Odometry(x.t, x.p.copy(), x.v.copy(), x.q.copy(), w_B, pose_cov_W=pose_cov, twist_cov_B=twist_cov)

    def _output_covariances(self, x: _State) -> tuple[np.ndarray, np.ndarray]:
        """The published estimate's covariances from the error covariance P, to first order: pose (dp_W, dtheta_W =
        R_WB dtheta_B) and twist (dv_B = R_WB^T dv_W + [v_B]x dtheta_B, dw_B = -db_g plus the gyro's white noise
        on the one sample the rate comes from: density^2 * rate_hz)."""
        R = quat_to_matrix(x.q)
        J = np.zeros((12, 15))
        J[0:3, 0:3] = np.eye(3)
        J[3:6, 6:9] = R
        J[6:9, 3:6] = R.T
        J[6:9, 6:9] = _skew(R.T @ x.v)
        J[9:12, 12:15] = -np.eye(3)
        C = J @ x.P @ J.T
        C[9:12, 9:12] += np.eye(3) * (self.params.gyro_noise_density**2 * self.rate_hz)
        C = 0.5 * (C + C.T)
        return C[0:6, 0:6].copy(), C[6:12, 6:12].copy()

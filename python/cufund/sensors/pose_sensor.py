"""A pose source: motion capture, or any slow odometry, as :class:`~cufund.core.messages.Odometry` on a topic."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cufund.core.components import Sensor
from cufund.core.config import check_at_most, check_real_fields
from cufund.core.messages import Odometry, Topics
from cufund.geometry import quat_mul


@dataclass(frozen=True)
class PoseSensorParams:
    """A pose source's output rate and errors (white, Gaussian, from the sensor's own seeded stream)."""

    rate_hz: float = 10.0
    """Output rate [Hz]."""
    position_sigma_m: float = 0.0
    """Position noise, per axis [m]."""
    attitude_sigma_rad: float = 0.0
    """Attitude noise, a small rotation per axis [rad]."""
    velocity_sigma_m_s: float = 0.0
    """Velocity noise, per axis [m/s]."""

    def __post_init__(self) -> None:
        check_real_fields(self, "PoseSensorParams")
        if self.rate_hz <= 0:
            raise ValueError(f"PoseSensorParams.rate_hz must be > 0 [Hz], got {self.rate_hz!r}")
        check_at_most(self, "PoseSensorParams", rate_hz=1e3)


class PoseSensor(Sensor):
    """Publishes the body pose and velocity (body rate too, noise-free) at ``params.rate_hz`` on ``topic``, each
    message stamped with its measurement time and visible ``latency_s`` later."""

    name = "pose"

    def __init__(self, params: PoseSensorParams | None = None, seed: int = 0, topic: str = Topics.POSE) -> None:
        self.params = params or PoseSensorParams()
        self.rate_hz, self.topic, self.seed = self.params.rate_hz, topic, int(seed)
        self.reset()

    def reset(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    def measure(self, t: float, truth: Odometry) -> Odometry:
        p = self.params
        noise = self._rng.standard_normal(9)
        q = truth.q_WB
        if p.attitude_sigma_rad > 0:
            dtheta = noise[3:6] * p.attitude_sigma_rad
            angle = float(np.linalg.norm(dtheta))
            axis = dtheta / angle if angle > 0 else np.zeros(3)
            q = quat_mul(np.asarray(q), np.r_[math.cos(angle / 2), math.sin(angle / 2) * axis])
        return Odometry(
            t, truth.p_W + p.position_sigma_m * noise[:3], truth.v_W + p.velocity_sigma_m_s * noise[6:9], q, truth.w_B
        )

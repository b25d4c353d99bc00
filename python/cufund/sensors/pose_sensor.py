"""A pose source: motion capture, or any slow odometry, as :class:`~cufund.core.messages.Pose` on a topic.

Motion capture measures where the markers are, not how fast they move: the message carries position and attitude
only (no velocity, no body rate), each stamped with its measurement time; the part's ``latency_s`` (scenario key)
delays its delivery. An estimator (:class:`cufund.estimation.ImuPropagator`) derives velocity and IMU biases.

Typical motion capture, for choosing the noise (1 sigma): Vicon and OptiTrack report sub-millimetre static and
about 1-2 mm dynamic position errors (Merriaux et al., "A Study of Vicon System Positioning Performance",
Sensors 17(7):1591, 2017; Furtado et al., "Comparative Analysis of OptiTrack Motion Capture Systems", 2019),
rigid-body attitude to about 0.1 deg, at 100-360 Hz; what reaches the vehicle (Vicon/Motive -> VRPN or ROS ->
the radio link) lags 5-20 ms (PX4's external-vision guide asks for that delay, ``EKF2_EV_DELAY``, to be
measured and set). ``square_mocap`` uses 0.5 mm, 0.1 deg, 100 Hz, 8 ms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cufund.core.components import Sensor
from cufund.core.config import check_at_most, check_real_fields
from cufund.core.messages import Odometry, Pose, Topics
from cufund.geometry import quat_from_rotvec, quat_mul

__all__ = ["PoseSensor", "PoseSensorParams"]


@dataclass(frozen=True)
class PoseSensorParams:
    """A pose source's output rate and errors (white, Gaussian, from the sensor's own seeded stream)."""

    rate_hz: float = 10.0
    """Output rate [Hz]."""
    position_sigma_m: float = 0.0
    """Position noise, per axis [m]."""
    attitude_sigma_rad: float = 0.0
    """Attitude noise, a small rotation per axis (body frame) [rad]."""

    def __post_init__(self) -> None:
        check_real_fields(self, "PoseSensorParams")
        if self.rate_hz <= 0:
            raise ValueError(f"PoseSensorParams.rate_hz must be > 0 [Hz], got {self.rate_hz!r}")
        check_at_most(self, "PoseSensorParams", rate_hz=1e3)


class PoseSensor(Sensor):
    """Publishes the measured body pose (:class:`Pose`: position and attitude, no velocity) at ``params.rate_hz``
    on ``topic``, each message stamped with its measurement time and visible ``latency_s`` later."""

    name = "pose"

    def __init__(self, params: PoseSensorParams | None = None, seed: int = 0, topic: str = Topics.POSE) -> None:
        self.params = params or PoseSensorParams()
        self.rate_hz, self.topic, self.seed = self.params.rate_hz, topic, int(seed)
        self.reset()

    def reset(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    def measure(self, t: float, truth: Odometry) -> Pose:
        p = self.params
        noise = self._rng.standard_normal(6)
        q = np.asarray(truth.q_WB, dtype=float)
        if p.attitude_sigma_rad > 0:
            q = quat_mul(q, quat_from_rotvec(noise[3:6] * p.attitude_sigma_rad))
        return Pose(t, truth.p_W + p.position_sigma_m * noise[:3], q)

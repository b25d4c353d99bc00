"""Template: a sensor. Copy, rename, replace the measurement model.

A :class:`cufund.Sensor` turns ground truth into a measurement on its ``topic``. This one is a position sensor
(e.g. motion capture) with Gaussian noise from its own seeded generator, so runs stay repeatable.
"""

from __future__ import annotations

import numpy as np

import cufund
from cufund.core.messages import Odometry


class MyPositionSensor(cufund.Sensor):
    name = "my_position_sensor"
    topic = cufund.Topic("/sensors/position", Odometry)  # a typed topic: the bus checks what is published

    def __init__(self, sigma_m: float = 0.01, rate_hz: float = 100.0, seed: int = 0) -> None:
        self.sigma, self.rate_hz, self.seed = sigma_m, rate_hz, seed
        self.rng = np.random.default_rng(seed)

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def measure(self, t: float, truth: Odometry) -> Odometry:
        noisy = truth.p_W + self.sigma * self.rng.standard_normal(3)
        return Odometry(t, noisy, truth.v_W, truth.q_WB, truth.w_B)

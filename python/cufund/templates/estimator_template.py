"""Template: an estimator. Copy, rename, replace the filter.

A :class:`cufund.Estimator` fuses measurements into an :class:`Odometry` on its ``topic``; once one is attached,
the attitude and position loops, mappers and planners fly on its output instead of ground truth (and the rate
loop on the IMU's gyro). This one low-pass filters the template position sensor's readings
(``/sensors/position``, :class:`~cufund.core.messages.Pose`), each reading exactly once (a subscription delivers
every message since the last run, however the rates compare); its velocity is the filtered position's difference
quotient, its attitude the reading's, its body rate zero (unknown: the rate loop flies on the gyro).
"""

from __future__ import annotations

import numpy as np

import cufund
from cufund.core.messages import Odometry


class MyEstimator(cufund.Estimator):
    name = "my_estimator"

    def __init__(self, input_topic: str = "/sensors/position", gain: float = 0.5, rate_hz: float = 100.0) -> None:
        self.input_topic, self.gain, self.rate_hz = input_topic, gain, rate_hz
        self.inputs = (input_topic,)  # declared inputs: the only topics it may read
        self.last: Odometry | None = None

    def reset(self) -> None:
        self.last = None

    def setup(self, bus: cufund.BusView) -> None:
        self.readings = bus.subscribe(self.input_topic)

    def estimate(self, t: float, bus: cufund.BusView) -> Odometry | None:
        readings = self.readings.take()  # every new reading, in order, once
        for z in readings:
            last = self.last
            p = z.p_W if last is None else last.p_W + self.gain * (z.p_W - last.p_W)
            v = (p - last.p_W) / (z.t - last.t) if last is not None and z.t > last.t else np.zeros(3)
            self.last = Odometry(z.t, p, v, z.q_WB, np.zeros(3))
        return self.last if readings else None  # publish only what is new

"""Template: a planner. Copy, rename, replace the plan.

A :class:`cufund.Planner` reads the state and publishes references for the controllers. This one circles the
point where the vehicle started, publishing position, velocity, acceleration and yaw on
``Topics.TRAJECTORY_SETPOINT`` (what the built-in position and geometric controllers track).
"""

from __future__ import annotations

import math

import numpy as np

import cufund
from cufund.core.messages import Odometry, Topics, TrajectorySetpoint


class MyPlanner(cufund.Planner):
    name = "my_planner"
    writes = (Topics.TRAJECTORY_SETPOINT,)

    def __init__(self, radius: float = 0.5, period: float = 8.0, rate_hz: float = 100.0) -> None:
        self.radius, self.omega, self.rate_hz = radius, 2.0 * math.pi / period, rate_hz
        self.center: np.ndarray | None = None

    def reset(self) -> None:
        self.center = None

    def update(self, t: float, state: Odometry, bus: cufund.BusView) -> None:
        if self.center is None:
            self.center = state.p_W - np.array([self.radius, 0.0, 0.0])
        r, w = self.radius, self.omega
        c, s = math.cos(w * t), math.sin(w * t)
        bus.publish(
            Topics.TRAJECTORY_SETPOINT,
            TrajectorySetpoint(
                t,
                self.center + r * np.array([c, s, 0.0]),
                r * w * np.array([-s, c, 0.0]),
                -r * w * w * np.array([c, s, 0.0]),
                r * w**3 * np.array([s, -c, 0.0]),
                0.0,
                0.0,
            ),
        )

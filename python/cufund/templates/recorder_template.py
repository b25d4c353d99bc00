"""Template: a recorder. Copy, rename, record what you need.

A :class:`cufund.Recorder` samples the bus at its own rate; its :meth:`histories` land in
``SimulationResult.recordings[name]``. This one records the distance between the vehicle and the current
trajectory setpoint.
"""

from __future__ import annotations

import numpy as np

import cufund
from cufund.core.messages import Odometry, Topics, TrajectorySetpoint


class MyRecorder(cufund.Recorder):
    name = "setpoint_distance"
    inputs = (Topics.TRUTH_ODOMETRY,)  # a recorder is a truth consumer: it may read /truth/ topics
    optional_inputs = (Topics.TRAJECTORY_SETPOINT,)

    def __init__(self, rate_hz: float = 50.0) -> None:
        self.rate_hz = rate_hz
        self.t: list[float] = []
        self.distance: list[float] = []

    def reset(self) -> None:
        self.t, self.distance = [], []

    def record(self, t: float, bus: cufund.BusView) -> None:
        truth: Odometry | None = bus.latest(Topics.TRUTH_ODOMETRY)
        sp: TrajectorySetpoint | None = bus.latest(Topics.TRAJECTORY_SETPOINT)
        if truth is not None and sp is not None:
            self.t.append(t)
            self.distance.append(float(np.linalg.norm(truth.p_W - sp.p_W)))

    def histories(self) -> dict[str, np.ndarray]:
        return {"t": np.array(self.t), "distance_m": np.array(self.distance)}

"""Template: a controller. Copy, rename, replace the control law.

A :class:`cufund.Controller` reads the state from its state topic (ground truth, or the estimator's output once
one is attached) and references from other topics, and publishes commands. This one is a hover controller that
commands collective thrust through the built-in allocator: vertical PD on the setpoint's height, level attitude
by a PD on the tilt, published as rotor speeds.
"""

from __future__ import annotations

import numpy as np

import cufund
from cufund.control import ControlAllocator
from cufund.core.messages import ActuatorCommand, Odometry, Topics, TrajectorySetpoint


class MyController(cufund.Controller):
    name = "my_controller"
    optional_reads = (Topics.TRAJECTORY_SETPOINT,)  # read if something publishes it (the state topic is implied)
    writes = (Topics.ACTUATOR_COMMAND,)

    def __init__(self, params: cufund.QuadrotorParams, rate_hz: float = 500.0) -> None:
        self.params = params
        self.rate_hz = rate_hz  # any positive rate
        self.allocator = ControlAllocator(params)

    def update(self, t: float, state: Odometry, bus: cufund.BusView) -> None:
        sp: TrajectorySetpoint | None = bus.latest(Topics.TRAJECTORY_SETPOINT)
        z_ref = sp.p_W[2] if sp is not None else state.p_W[2]
        m, g = self.params.mass, self.params.gravity
        thrust = m * (g + 4.0 * (z_ref - state.p_W[2]) - 3.0 * state.v_W[2])
        w, x, y, _ = state.q_WB
        tilt = 2.0 * np.array([w * x, w * y, 0.0])  # small-angle roll and pitch error (vector part of q)
        torque = self.params.inertia_matrix @ (-100.0 * tilt - 20.0 * state.w_B)
        bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand(t, self.allocator.rotor_speeds(thrust, torque)))

"""PX4-style attitude control (``mc_att_control``): P on the quaternion error with reduced yaw priority."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cufund import _core
from cufund.core.components import BusView, Controller
from cufund.core.config import check_real_fields
from cufund.core.messages import AttitudeSetpoint, Odometry, RateSetpoint, Topics

from .arming import Gate, gate

__all__ = ["AttitudeControlParams", "AttitudeController"]


@dataclass(frozen=True)
class AttitudeControlParams:
    """Gains [1/s] and rate limits [rad/s]; PX4 names in brackets (PX4's limits are in deg/s)."""

    roll_p: float = 6.5
    """(MC_ROLL_P)"""
    pitch_p: float = 6.5
    """(MC_PITCH_P)"""
    yaw_p: float = 2.8
    """(MC_YAW_P). As in PX4, yaw_p / mean(roll_p, pitch_p) is the yaw weight of the reduced-priority error."""
    roll_rate_max: float = math.radians(220.0)
    """(MC_ROLLRATE_MAX)"""
    pitch_rate_max: float = math.radians(220.0)
    """(MC_PITCHRATE_MAX)"""
    yaw_rate_max: float = math.radians(200.0)
    """(MC_YAWRATE_MAX)"""

    def __post_init__(self) -> None:
        check_real_fields(self, "AttitudeControlParams", positive=True)


class AttitudeController(Controller):
    """Tracks ``Topics.ATTITUDE_SETPOINT`` and publishes a :class:`RateSetpoint` on ``Topics.RATE_SETPOINT``.

    PX4's reduced yaw priority: the desired attitude is split into the shortest tilt that aligns the thrust
    axes and a remaining rotation about the desired thrust axis, whose angle is scaled by the yaw weight; the
    rate setpoint is the gains times twice the vector part of the resulting error quaternion, plus the yaw-rate
    feed-forward about world z expressed in the body frame.
    """

    name = "attitude_controller"
    reads = (Topics.ATTITUDE_SETPOINT,)
    writes = (Topics.RATE_SETPOINT,)
    armable = False
    """Gated by a commander's vehicle status (:func:`cufund.control.arming.make_armable`)."""

    def __init__(self, gains: AttitudeControlParams | None = None, rate_hz: float = 250.0) -> None:
        self._core = _core.control.AttitudeControl()  # the arithmetic, in C++ (cpp/control/attitude_control.cpp)
        self.set_gains(gains or AttitudeControlParams())
        self.rate_hz = rate_hz

    def set_gains(self, gains: AttitudeControlParams) -> None:
        """Replaces the gains, also in flight; the controller's state is kept."""
        self.gains = g = gains
        rp = 0.5 * (g.roll_p + g.pitch_p)
        self.yaw_weight = min(max(g.yaw_p / rp, 0.0), 1.0)
        self._core.set_gains(
            np.array([g.roll_p, g.pitch_p, rp]),
            np.array([g.roll_rate_max, g.pitch_rate_max, g.yaw_rate_max]),
            self.yaw_weight,
        )

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if self.armable and gate(bus, "pid") is not Gate.FLY:  # disarmed, idle on the ground, or geometric flies
            return
        sp: AttitudeSetpoint | None = bus.latest(Topics.ATTITUDE_SETPOINT)
        if sp is None:
            return
        w_sp = self._core.rate_setpoint(state.q_WB, sp.q_WB, sp.yaw_rate)  # fresh and read-only
        bus.publish(Topics.RATE_SETPOINT, RateSetpoint.trusted(t, w_sp, sp.thrust))

"""PX4-style attitude control (``mc_att_control``): P on the quaternion error with reduced yaw priority."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import check_real_fields
from ..components import Bus, Controller
from ..messages import AttitudeSetpoint, Odometry, RateSetpoint, Topics
from .arming import Gate, gate
from .rotations import quat_conjugate, quat_from_two_vectors, quat_multiply, quat_to_rotation

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
        self.set_gains(gains or AttitudeControlParams())
        self.rate_hz = rate_hz

    def set_gains(self, gains: AttitudeControlParams) -> None:
        """Replaces the gains, also in flight; the controller's state is kept."""
        self.gains = g = gains
        rp = 0.5 * (g.roll_p + g.pitch_p)
        self.yaw_weight = min(max(g.yaw_p / rp, 0.0), 1.0)
        self._k = np.array([g.roll_p, g.pitch_p, rp])
        self._max = np.array([g.roll_rate_max, g.pitch_rate_max, g.yaw_rate_max])

    def update(self, t: float, state: Odometry, bus: Bus) -> None:
        if self.armable and gate(bus, "pid") is not Gate.FLY:  # disarmed, idle on the ground, or geometric flies
            return
        sp: AttitudeSetpoint | None = bus.latest(Topics.ATTITUDE_SETPOINT)
        if sp is None:
            return
        q = state.q_WB
        qd = sp.q_WB
        R = quat_to_rotation(q)
        e_z, e_z_d = R[:, 2], quat_to_rotation(qd)[:, 2]
        qd_red = quat_from_two_vectors(e_z, e_z_d)
        if abs(qd_red[1]) > 1 - 1e-5 or abs(qd_red[2]) > 1 - 1e-5:
            qd_red = qd  # thrust axes opposite: the full attitude is the only well-defined target
        else:
            qd_red = quat_multiply(qd_red, q)
        q_mix = quat_multiply(quat_conjugate(qd_red), qd)
        if q_mix[0] < 0:
            q_mix = -q_mix
        w_mix = min(max(q_mix[0], -1.0), 1.0)
        z_mix = min(max(q_mix[3], -1.0), 1.0)
        yw = self.yaw_weight
        qd = quat_multiply(qd_red, np.array([math.cos(yw * math.acos(w_mix)), 0.0, 0.0, math.sin(yw * math.asin(z_mix))]))
        qe = quat_multiply(quat_conjugate(q), qd)
        if qe[0] < 0:
            qe = -qe
        w_sp = 2.0 * qe[1:] * self._k
        if sp.yaw_rate:
            w_sp += R[2, :] * sp.yaw_rate  # world z in the body frame, times the yaw-rate feed-forward
        w_sp = np.minimum(np.maximum(w_sp, -self._max), self._max)
        bus.publish(Topics.RATE_SETPOINT, RateSetpoint(t, w_sp, sp.thrust))

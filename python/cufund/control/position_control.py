"""PX4-style multicopter position control (``mc_pos_control``): position P -> velocity PID -> acceleration ->
thrust vector and attitude setpoint (paper §2.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cufund import _core
from cufund.core.components import BusView, Controller
from cufund.core.config import check_real_fields
from cufund.core.messages import AttitudeSetpoint, FlightMode, Odometry, Topics
from cufund.geometry import quat_to_matrix
from cufund.vehicle.params import QuadrotorParams

from .arming import Gate, gate
from .flight_mode import BumplessTransfer, ModeReferences

__all__ = ["PositionControlParams", "PositionController"]


@dataclass(frozen=True)
class PositionControlParams:
    """Gains and limits. PX4 parameter names in brackets; units are PX4's (its velocity gains are already in
    m/s^2 per m/s, so the numbers carry over)."""

    xy_p: float = 0.95
    """Horizontal position gain [1/s] (MPC_XY_P)."""
    z_p: float = 1.0
    """Vertical position gain [1/s] (MPC_Z_P)."""
    xy_vel_p: float = 1.8
    """Horizontal velocity P [m/s^2 per m/s] (MPC_XY_VEL_P_ACC)."""
    xy_vel_i: float = 0.4
    """Horizontal velocity I [m/s^3 per m/s] (MPC_XY_VEL_I_ACC)."""
    xy_vel_d: float = 0.2
    """Horizontal velocity D on the measured acceleration [m/s^2 per m/s^2] (MPC_XY_VEL_D_ACC)."""
    z_vel_p: float = 4.0
    """Vertical velocity P (MPC_Z_VEL_P_ACC)."""
    z_vel_i: float = 2.0
    """Vertical velocity I (MPC_Z_VEL_I_ACC)."""
    z_vel_d: float = 0.0
    """Vertical velocity D (MPC_Z_VEL_D_ACC)."""
    vel_d_cutoff_hz: float = 5.0
    """Low-pass cutoff of the velocity derivative used by D [Hz] (MPC_VELD_LP)."""
    xy_vel_max: float = 12.0
    """Horizontal velocity setpoint limit [m/s] (MPC_XY_VEL_MAX)."""
    z_vel_max_up: float = 3.0
    """Climb rate limit [m/s] (MPC_Z_VEL_MAX_UP)."""
    z_vel_max_dn: float = 1.5
    """Descent rate limit [m/s] (MPC_Z_VEL_MAX_DN)."""
    tilt_max: float = math.radians(45.0)
    """Largest tilt of the thrust vector [rad] (MPC_TILTMAX_AIR, there in degrees)."""
    thr_min: float = 0.12
    """Lowest collective thrust as a fraction of the maximum (MPC_THR_MIN)."""
    thr_max: float = 1.0
    """Highest collective thrust as a fraction of the maximum (MPC_THR_MAX)."""

    def __post_init__(self) -> None:
        check_real_fields(self, "PositionControlParams")
        if not 0 < self.tilt_max < math.pi / 2:
            raise ValueError(f"PositionControlParams.tilt_max must be in (0, pi/2) rad, got {self.tilt_max}")
        if not 0 <= self.thr_min < self.thr_max <= 1:
            raise ValueError(
                f"PositionControlParams needs 0 <= thr_min < thr_max <= 1, got {self.thr_min}, {self.thr_max}"
            )


class PositionController(Controller):
    """Position and velocity modes: tracks ``Topics.TRAJECTORY_SETPOINT`` (position, velocity, acceleration and
    yaw-rate feed-forward) and publishes an :class:`AttitudeSetpoint` on ``Topics.ATTITUDE_SETPOINT``. In
    attitude mode it forwards ``Topics.MANUAL_ATTITUDE_SETPOINT``. Switching modes hands the velocity integrator
    over without a jump: references are held as described in :class:`ModeReferences`, and the step between the
    last and the new acceleration command fades out (:class:`BumplessTransfer`).

    The thrust model uses the vehicle mass from ``params`` where PX4 uses its hover-thrust estimate.
    """

    name = "position_controller"
    optional_reads = ModeReferences.TOPICS
    writes = (Topics.ATTITUDE_SETPOINT,)
    armable = False
    """Gated by a commander's vehicle status (:func:`cufund.control.arming.make_armable`)."""

    def __init__(
        self,
        params: QuadrotorParams,
        gains: PositionControlParams | None = None,
        rate_hz: float = 250.0,
        mode: FlightMode = FlightMode.POSITION,
        max_thrust: float | None = None,
    ) -> None:
        self.params = params
        self.rate_hz = rate_hz
        self.refs = ModeReferences(mode)
        self.transfer_tau = BumplessTransfer().tau
        """Decay of the step a mode switch would cause in the acceleration command [s] (see BumplessTransfer)."""
        self.max_thrust = max_thrust if max_thrust is not None else 4.0 * params.k_f * params.rotor_speed_max**2
        g = gains or PositionControlParams()
        # the step's arithmetic, in C++ (cpp/control/position_control.cpp); the mode logic stays here
        self._core = _core.control.PositionControl(
            params.mass, params.gravity, self.max_thrust, g.vel_d_cutoff_hz, self.transfer_tau
        )
        self.set_gains(g)
        self.reset()

    def set_gains(self, gains: PositionControlParams) -> None:
        """Replaces the gains, also in flight; the controller's state is kept (a filter cutoff keeps the value it
        was built with)."""
        self.gains = g = gains
        self._core.set_gains(
            np.array([g.xy_p, g.xy_p, g.z_p]),
            np.array([g.xy_vel_p, g.xy_vel_p, g.z_vel_p]),
            np.array([g.xy_vel_i, g.xy_vel_i, g.z_vel_i]),
            np.array([g.xy_vel_d, g.xy_vel_d, g.z_vel_d]),
            g.xy_vel_max,
            g.z_vel_max_up,
            g.z_vel_max_dn,
            g.tilt_max,
            g.thr_min,
            g.thr_max,
        )

    def reset(self) -> None:
        self.refs.reset()
        self._core.reset()
        self.last: AttitudeSetpoint | None = None

    @property
    def vel_int(self) -> np.ndarray:
        """Velocity integrator [m/s^2] (a copy)."""
        return self._core.vel_int

    @property
    def mode(self) -> FlightMode:
        return self.refs.mode

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if self.armable and gate(bus, "pid") is not Gate.FLY:  # disarmed, idle on the ground, or geometric flies
            self.reset()
            return
        dt = 1.0 / self.rate_hz
        refs = self.refs
        mode = refs.update(t, state, bus, self.last)
        if mode is FlightMode.ATTITUDE:
            # the velocity derivative for D keeps running in every mode, so D does not kick after a switch
            self._core.filter_velocity(state.v_W, dt)
            att = refs.attitude(bus)
            m = self.params.mass
            thrust = m * self.params.gravity if math.isnan(att.thrust) else att.thrust
            self.last = AttitudeSetpoint(t, att.q_WB, thrust, att.yaw_rate)
            bus.publish(Topics.ATTITUDE_SETPOINT, self.last)
            return
        sp = refs.trajectory(t, bus)
        handover = None
        if refs.switched and self.last is not None:
            # hand over: the acceleration last commanded (in any mode) continues and fades into the new one
            z_prev = quat_to_matrix(self.last.q_WB)[:, 2]
            handover = self.last.thrust / self.params.mass * z_prev - np.array([0.0, 0.0, self.params.gravity])
        q, thrust = self._core.step(
            t, dt, state.p_W, state.v_W, sp.p_W, sp.v_W, sp.a_W, sp.yaw, mode is FlightMode.POSITION, handover
        )
        self.last = AttitudeSetpoint.trusted(t, q, thrust, sp.yaw_rate)  # q: fresh and read-only
        bus.publish(Topics.ATTITUDE_SETPOINT, self.last)

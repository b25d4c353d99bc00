"""PX4-style multicopter position control (``mc_pos_control``): position P -> velocity PID -> acceleration ->
thrust vector and attitude setpoint (paper §2.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import check_real_fields
from ..components import Bus, Controller
from ..messages import AttitudeSetpoint, FlightMode, Odometry, Topics
from ..params import QuadrotorParams
from .arming import Gate, gate
from .derivative_filter import LowPassDerivative
from .flight_mode import BumplessTransfer, ModeReferences
from .rotations import attitude_from_thrust_and_yaw, quat_to_rotation, rotation_to_quat

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
            raise ValueError(f"PositionControlParams needs 0 <= thr_min < thr_max <= 1, got {self.thr_min}, {self.thr_max}")


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

    def __init__(self, params: QuadrotorParams, gains: PositionControlParams | None = None, rate_hz: float = 250.0,
                 mode: FlightMode = FlightMode.POSITION, max_thrust: float | None = None) -> None:
        self.params = params
        self.set_gains(gains or PositionControlParams())
        self.rate_hz = rate_hz
        self.refs = ModeReferences(mode)
        self.transfer = BumplessTransfer()
        self.max_thrust = max_thrust if max_thrust is not None else 4.0 * params.k_f * params.rotor_speed_max ** 2
        self._acc = LowPassDerivative(self.gains.vel_d_cutoff_hz)
        self.reset()

    def set_gains(self, gains: PositionControlParams) -> None:
        """Replaces the gains, also in flight; the controller's state is kept (a filter cutoff keeps the value it
        was built with)."""
        self.gains = g = gains
        self._kp = np.array([g.xy_p, g.xy_p, g.z_p])
        self._kv = np.array([g.xy_vel_p, g.xy_vel_p, g.z_vel_p])
        self._ki = np.array([g.xy_vel_i, g.xy_vel_i, g.z_vel_i])
        self._kd = np.array([g.xy_vel_d, g.xy_vel_d, g.z_vel_d])

    def reset(self) -> None:
        self.refs.reset()
        self.transfer.reset()
        self.vel_int = np.zeros(3)
        """Velocity integrator [m/s^2]."""
        self._acc.reset()
        self.last: AttitudeSetpoint | None = None

    @property
    def mode(self) -> FlightMode:
        return self.refs.mode

    def update(self, t: float, state: Odometry, bus: Bus) -> None:
        if self.armable and gate(bus, "pid") is not Gate.FLY:  # disarmed, idle on the ground, or geometric flies
            self.reset()
            return
        g = self.gains
        m, grav = self.params.mass, self.params.gravity
        dt = 1.0 / self.rate_hz
        mode = self.refs.update(t, state, bus, self.last)
        # velocity derivative for D, low-passed; kept running in every mode so D does not kick after a switch
        acc_filt = self._acc.update(state.v_W, dt)
        if mode is FlightMode.ATTITUDE:
            att = self.refs.attitude(bus)
            thrust = m * grav if math.isnan(att.thrust) else att.thrust
            self.last = AttitudeSetpoint(t, att.q_WB, thrust, att.yaw_rate)
            bus.publish(Topics.ATTITUDE_SETPOINT, self.last)
            return
        sp = self.refs.trajectory(t, bus)
        if mode is FlightMode.POSITION:
            v_sp = self._kp * (sp.p_W - state.p_W) + sp.v_W
        else:
            v_sp = sp.v_W.copy()
        vxy = math.hypot(v_sp[0], v_sp[1])
        if vxy > g.xy_vel_max:
            v_sp[:2] *= g.xy_vel_max / vxy
        v_sp[2] = min(max(v_sp[2], -g.z_vel_max_dn), g.z_vel_max_up)
        v_err = v_sp - state.v_W
        acc_sp = self._kv * v_err + self.vel_int - self._kd * acc_filt + sp.a_W
        if self.refs.switched and self.last is not None:
            # hand over: the acceleration last commanded (in any mode) continues and fades into the new one
            z_prev = quat_to_rotation(self.last.q_WB)[:, 2]
            self.transfer.start(t, self.last.thrust / m * z_prev - np.array([0.0, 0.0, grav]), acc_sp)
        acc_sp = acc_sp + self.transfer.offset(t)
        F, sat = self._thrust_vector(m * (acc_sp + np.array([0.0, 0.0, grav])))
        # integrate unless the thrust vector saturated in the direction the error pushes (anti-windup)
        push = self._ki * v_err * dt
        keep = ~((sat > 0) & (push > 0) | (sat < 0) & (push < 0))
        self.vel_int += np.where(keep, push, 0.0)
        lim = grav  # no more than 1 g from the integrator on any axis
        self.vel_int = np.minimum(np.maximum(self.vel_int, -lim), lim)
        thrust = float(np.linalg.norm(F))
        R_d = attitude_from_thrust_and_yaw(F / thrust, sp.yaw)
        self.last = AttitudeSetpoint(t, rotation_to_quat(R_d), thrust, sp.yaw_rate)
        bus.publish(Topics.ATTITUDE_SETPOINT, self.last)

    def _thrust_vector(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Limits thrust magnitude and tilt; returns the limited vector and per-axis saturation signs."""
        g = self.gains
        sat = np.zeros(3)
        f_min, f_max = g.thr_min * self.max_thrust, g.thr_max * self.max_thrust
        F = F.copy()
        if F[2] < f_min * math.cos(g.tilt_max):
            F[2] = f_min * math.cos(g.tilt_max)
            sat[2] = -1
        h = math.hypot(F[0], F[1])
        h_max = F[2] * math.tan(g.tilt_max)
        if h > h_max:
            F[:2] *= h_max / h
            sat[:2] = np.sign(F[:2])
        n = float(np.linalg.norm(F))
        if n > f_max:
            # keep the vertical component first (PX4 prioritises altitude), then what is left horizontally
            if F[2] >= f_max:
                F = np.array([0.0, 0.0, f_max])
            else:
                hh = math.sqrt(f_max * f_max - F[2] * F[2])
                F[:2] *= hh / max(math.hypot(F[0], F[1]), 1e-12)
                sat[:2] = np.sign(F[:2])
            sat[2] = 1
        elif n < f_min:
            F *= f_min / max(n, 1e-12)
            sat[2] = -1
        return F, sat

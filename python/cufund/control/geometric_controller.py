"""Nonlinear geometric tracking control on SE(3) (Lee, Leok & McClamroch, CDC 2010), in world ENU / body FLU.

Position mode:  F = -k_x e_x - k_i int(e_x) - k_v e_v + m g e_3 + m a_d,   f = F . R e_3,   b_3d = F / |F|
Attitude:       e_R = 1/2 vee(R_d^T R - R^T R_d),   e_W = W - R^T R_d W_d
                M = -k_R e_R - k_W e_W + W x J W - J (hat(W) R^T R_d W_d - R^T R_d dW_d)
with the desired body rate W_d from the jerk feed-forward (differential flatness; dW_d taken as zero).
Velocity mode drops the position term; attitude mode tracks a given attitude and thrust. Gains are scaled by
the mass (k_x, k_i, k_v) and the inertia (k_R, k_W), so they are accelerations per unit error. The integral of the
position error (Lee's integral term, as in Goodarzi, Lee & Lee, 2015) takes up what the model gets wrong: a mass
or thrust constant a few percent off leaves a steady offset of g times the error over k_x (8 cm at 5 %) without
it. It accumulates in position mode only, the error saturated at i_band, bounded so that k_i |int(e_x)| <= i_max. The force law and the
mode logic are here; the force law, the attitude law and the allocation run in C++, one call per step
(``cpp/control/geometric_control.cpp``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cufund import _core
from cufund.core.components import BusView, Controller
from cufund.core.config import ConfigError, check_real_fields
from cufund.core.messages import ActuatorCommand, AttitudeSetpoint, FlightMode, Odometry, ThrustTorqueSetpoint, Topics
from cufund.geometry import quat_to_matrix
from cufund.vehicle.params import QuadrotorParams

from .arming import gated
from .flight_mode import BumplessTransfer, ModeReferences
from .gyro_input import GyroInput

__all__ = ["GeometricControlParams", "GeometricController"]


@dataclass(frozen=True)
class GeometricControlParams:
    """Gains of the SE(3) controller, as accelerations per unit error."""

    k_x: float = 6.0
    """Position gain [m/s^2 per m] (times the mass gives Lee's k_x)."""
    k_v: float = 4.5
    """Velocity gain [m/s^2 per m/s]."""
    k_i: float = 0.0
    """Gain on the integral of the position error [m/s^2 per m s] (0: Lee's law without it; below k_x k_v for
    stability)."""
    i_max: float = 2.0
    """Largest acceleration the integral term may ask for [m/s^2] (anti-windup)."""
    i_band: float = 0.15
    """The position error is integrated saturated at this length [m] (a transient winds the integral up no faster
    than a steady offset of i_band would)."""
    k_R: float = 150.0
    """Attitude gain [rad/s^2 per rad] (times J gives Lee's k_R)."""
    k_W: float = 22.0
    """Body-rate gain [rad/s^2 per rad/s]."""
    k_R_yaw: float = 40.0
    """Attitude gain about body z [rad/s^2 per rad]."""
    k_W_yaw: float = 10.0
    """Body-rate gain about body z [rad/s^2 per rad/s]."""

    def __post_init__(self) -> None:
        check_real_fields(self, "GeometricControlParams")
        if self.k_i < 0 or self.i_max < 0 or self.i_band <= 0:
            raise ConfigError(
                f"GeometricControlParams: k_i and i_max must be >= 0 and i_band > 0, got {self.k_i!r}, "
                f"{self.i_max!r}, {self.i_band!r}"
            )
        if self.k_i >= self.k_x * self.k_v:
            raise ConfigError(
                f"GeometricControlParams.k_i must be below k_x * k_v = {self.k_x * self.k_v:g} (stability of "
                f"s^3 + k_v s^2 + k_x s + k_i), got {self.k_i!r}"
            )


class GeometricController(Controller):
    """The SE(3) controller as one component: references in (``Topics.TRAJECTORY_SETPOINT``, or
    ``Topics.MANUAL_ATTITUDE_SETPOINT`` in attitude mode), rotor speeds out (``Topics.ACTUATOR_COMMAND``),
    through the same prioritising :class:`ControlAllocator` as the cascaded PID. Mode switches hold the
    references the vehicle had at the switch (see :class:`ModeReferences`) and fade out the step between the
    last and the new force command (:class:`BumplessTransfer`). With an estimator attached, position, velocity and
    attitude come from the estimate and the body rate from the IMU's gyro (as :class:`RateController`)."""

    name = "geometric_controller"
    optional_reads = ModeReferences.TOPICS
    writes = (Topics.ATTITUDE_SETPOINT, Topics.THRUST_TORQUE_SETPOINT, Topics.ACTUATOR_COMMAND)
    armable = False
    """Gated by a commander's vehicle status (:func:`cufund.control.arming.make_armable`)."""

    def __init__(
        self,
        params: QuadrotorParams,
        gains: GeometricControlParams | None = None,
        rate_hz: float = 500.0,
        mode: FlightMode = FlightMode.POSITION,
        q_BI: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
        gyro_cutoff_hz: float = 40.0,
    ) -> None:
        self.params = params
        self.gyro = GyroInput(q_BI, gyro_cutoff_hz)
        self.use_gyro = False
        # force law, attitude law and allocation in one C++ call per step (cpp/control/geometric_control.cpp)
        self._core = _core.control.GeometricControl(params.to_core(), BumplessTransfer().tau)
        self.set_gains(gains or GeometricControlParams())
        self.rate_hz = rate_hz
        self.refs = ModeReferences(mode)
        self.last: AttitudeSetpoint | None = None
        self.reset()

    def set_gains(self, gains: GeometricControlParams) -> None:
        """Replaces the gains, also in flight; the controller's state is kept."""
        self.gains = g = gains
        self._core.set_gains(g.k_x, g.k_v, np.array([g.k_R, g.k_R, g.k_R_yaw]), np.array([g.k_W, g.k_W, g.k_W_yaw]))

    def use_estimator(self, attached: bool) -> None:
        self.use_gyro = attached

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.active_state_topic, Topics.IMU) if self.use_gyro else (self.active_state_topic,)

    def reset(self) -> None:
        self.refs.reset()
        self._core.reset()
        self.gyro.reset()
        self.last = None
        self._int_e = np.zeros(3)
        self._t_int: float | None = None

    def setup(self, bus: BusView) -> None:
        if self.use_gyro:
            self.gyro.setup(bus)

    @property
    def mode(self) -> FlightMode:
        return self.refs.mode

    def _integral(self, t: float, e_x: np.ndarray, a_sp: np.ndarray, position: bool) -> np.ndarray:
        """The acceleration set-point with the integral term, -k_i int(e_x), added (bounded by i_max)."""
        g = self.gains
        if g.k_i <= 0.0:
            return a_sp
        if not position:
            self._t_int = None  # velocity or attitude mode: the integral holds
            return a_sp
        e = np.asarray(e_x, dtype=float)
        # the error integrated is saturated at i_band: a transient (a take-off catching up, a step in the set-point)
        # winds it up no faster than a steady offset of i_band would, while any steady offset is taken up; one
        # step's worth at most (no catching up over a pause in the state stream)
        n_e = float(np.linalg.norm(e))
        if n_e > g.i_band:
            e = e * (g.i_band / n_e)
        if self._t_int is not None:
            self._int_e += e * min(t - self._t_int, 2.0 / self.rate_hz)
            n = float(np.linalg.norm(self._int_e)) * g.k_i
            if n > g.i_max:
                self._int_e *= g.i_max / n
        self._t_int = t
        return np.asarray(a_sp, dtype=float) - g.k_i * self._int_e

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if gated(self, t, bus, "geometric"):
            return
        w_B = state.w_B
        if self.use_gyro:
            w_gyro = self.gyro.update()
            if w_gyro is None:
                return
            w_B = w_gyro
        mode = self.refs.update(t, state, bus, self.last)
        if mode is FlightMode.ATTITUDE:
            att = self.refs.attitude(bus)
            m, grav = self.params.mass, self.params.gravity
            f = m * grav if math.isnan(att.thrust) else att.thrust
            q_d, thrust, speeds, f_a, torque = self._core.step_attitude(state.q_WB, w_B, att.q_WB, f, att.yaw_rate)
            yaw_rate = att.yaw_rate
        else:
            sp = self.refs.trajectory(t, bus)
            handover = None
            if self.refs.switched and self.last is not None:
                # the force last commanded continues and fades into the new one
                handover = self.last.thrust * quat_to_matrix(self.last.q_WB)[:, 2]
            q_d, thrust, speeds, f_a, torque = self._core.step_force(
                t,
                state.p_W,
                state.v_W,
                state.q_WB,
                w_B,
                sp.p_W,
                sp.v_W,
                self._integral(t, state.p_W - sp.p_W, sp.a_W, mode is FlightMode.POSITION),
                sp.j_W,
                sp.yaw,
                sp.yaw_rate,
                mode is FlightMode.POSITION,
                handover,
            )
            yaw_rate = sp.yaw_rate
        # fresh, read-only arrays: the messages take them as they are
        self.last = AttitudeSetpoint.trusted(t, q_d, thrust, yaw_rate)
        bus.publish(Topics.ATTITUDE_SETPOINT, self.last)
        bus.publish(Topics.THRUST_TORQUE_SETPOINT, ThrustTorqueSetpoint.trusted(t, f_a, torque))
        bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand.trusted(t, speeds))

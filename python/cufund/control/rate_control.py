"""PX4-style body-rate control (``mc_rate_control``) followed by control allocation (``control_allocator``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cufund import _core
from cufund.core.components import BusView, Controller
from cufund.core.config import check_real_fields
from cufund.core.messages import ActuatorCommand, Odometry, RateSetpoint, ThrustTorqueSetpoint, Topics
from cufund.vehicle.params import QuadrotorParams

from .arming import gated
from .gyro_input import GyroInput

__all__ = ["RateControlParams", "RateController"]

_RATE_I_SCALE = math.radians(400.0)  # PX4: integration slows for rate errors near 400 deg/s


@dataclass(frozen=True)
class RateControlParams:
    """Rate PID gains. PX4 names in brackets; PX4's gains act on normalised actuator outputs, these on angular
    acceleration (torque = J * output), so they play the same role with vehicle-independent units: P
    [rad/s^2 per rad/s], I [rad/s^2 per rad], D [rad/s^2 per rad/s^2], FF [rad/s^2 per rad/s]."""

    roll_p: float = 25.0
    """(MC_ROLLRATE_P)"""
    roll_i: float = 10.0
    """(MC_ROLLRATE_I)"""
    roll_d: float = 0.2
    """(MC_ROLLRATE_D)"""
    pitch_p: float = 25.0
    """(MC_PITCHRATE_P)"""
    pitch_i: float = 10.0
    """(MC_PITCHRATE_I)"""
    pitch_d: float = 0.2
    """(MC_PITCHRATE_D)"""
    yaw_p: float = 12.0
    """(MC_YAWRATE_P)"""
    yaw_i: float = 5.0
    """(MC_YAWRATE_I)"""
    yaw_d: float = 0.0
    """(MC_YAWRATE_D)"""
    feed_forward: float = 0.0
    """Rate feed-forward on all axes (MC_ROLLRATE_FF, MC_PITCHRATE_FF, MC_YAWRATE_FF)."""
    integrator_limit: float = 30.0
    """Integrator magnitude limit per axis [rad/s^2] (MC_RR_INT_LIM, MC_PR_INT_LIM, MC_YR_INT_LIM)."""
    d_cutoff_hz: float = 30.0
    """Low-pass cutoff of the rate derivative used by D [Hz] (IMU_DGYRO_CUTOFF)."""

    def __post_init__(self) -> None:
        check_real_fields(self, "RateControlParams")


class RateController(Controller):
    """Tracks ``Topics.RATE_SETPOINT``; publishes :class:`ActuatorCommand` on ``Topics.ACTUATOR_COMMAND`` (and
    the allocated thrust and torque on ``Topics.THRUST_TORQUE_SETPOINT``).

    Its body-rate input, as PX4's: with an estimator attached, the IMU's gyro (every sample on ``Topics.IMU``,
    rotated by the IMU mounting ``q_BI`` and low-passed at ``gyro_cutoff_hz``), never the estimate; without one,
    the state topic's ``w_B`` (ground truth).

    PID with the derivative on the measured rate (low-passed), so setpoint steps do not kick; the integrator
    grows less for large errors (PX4's ``1 - (e / 400 deg/s)^2`` factor), stops on an axis whose torque the
    allocator could not deliver in the error's direction, and is limited in magnitude.
    """

    name = "rate_controller"
    reads = (Topics.RATE_SETPOINT,)
    writes = (Topics.ACTUATOR_COMMAND, Topics.THRUST_TORQUE_SETPOINT)
    armable = False
    """Gated by a commander's vehicle status (:func:`cufund.control.arming.make_armable`)."""
    gate_kind = "pid"
    """The controller kind whose selection by the commander lets it fly (``policy`` under a learned policy)."""

    def __init__(
        self,
        params: QuadrotorParams,
        gains: RateControlParams | None = None,
        rate_hz: float = 500.0,
        q_BI: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
        gyro_cutoff_hz: float = 40.0,
    ) -> None:
        self.params = params
        self.gyro = GyroInput(q_BI, gyro_cutoff_hz)
        self.use_gyro = False
        """True when the body rate comes from the IMU (set by the simulator: an estimator is attached)."""
        g = gains or RateControlParams()
        # the PID step and the allocation, in C++ (cpp/control/rate_control.cpp)
        self._core = _core.control.RateControl(params.to_core(), g.d_cutoff_hz, _RATE_I_SCALE)
        self.set_gains(g)
        self.rate_hz = rate_hz
        self.reset()

    def set_gains(self, gains: RateControlParams) -> None:
        """Replaces the gains, also in flight; the controller's state is kept (a filter cutoff keeps the value it
        was built with)."""
        self.gains = g = gains
        self._core.set_gains(
            np.array([g.roll_p, g.pitch_p, g.yaw_p]),
            np.array([g.roll_i, g.pitch_i, g.yaw_i]),
            np.array([g.roll_d, g.pitch_d, g.yaw_d]),
            g.feed_forward,
            g.integrator_limit,
        )

    def use_estimator(self, attached: bool) -> None:
        self.use_gyro = attached

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (Topics.IMU, *self.reads) if self.use_gyro else (self.active_state_topic, *self.reads)

    def reset(self) -> None:
        self._core.reset()
        self.gyro.reset()

    @property
    def rate_int(self) -> np.ndarray:
        """Rate integrator [rad/s^2] (a copy)."""
        return self._core.rate_int

    def setup(self, bus: BusView) -> None:
        if self.use_gyro:
            self.gyro.setup(bus)

    def step(self, t: float, bus: BusView) -> None:
        if gated(self, t, bus, self.gate_kind):
            return
        if self.use_gyro:
            w = self.gyro.update()
        else:
            state = bus.latest(self.active_state_topic)
            w = None if state is None else state.w_B
        if w is not None:
            self.control(t, w, bus)

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        self.control(t, state.w_B, bus)

    def control(self, t: float, w: np.ndarray, bus: BusView) -> None:
        """One step of the rate loop with measured body rate ``w`` [rad/s]."""
        sp: RateSetpoint | None = bus.latest(Topics.RATE_SETPOINT)
        if sp is None:
            return
        speeds, thrust, torque, _ = self._core.step(w, sp.w_B, sp.thrust, 1.0 / self.rate_hz)
        # fresh, read-only arrays: the messages take them as they are
        bus.publish(Topics.THRUST_TORQUE_SETPOINT, ThrustTorqueSetpoint.trusted(t, thrust, torque))
        bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand.trusted(t, speeds))

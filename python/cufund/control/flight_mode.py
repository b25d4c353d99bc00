"""Flight-mode switching shared by the controllers: which references are active, and what holds them right
after a switch so that no reference jumps (paper §2.3: attitude, velocity and position modes)."""

from __future__ import annotations

import math

import numpy as np

from cufund.core.components import BusView
from cufund.core.messages import AttitudeSetpoint, FlightMode, FlightModeCommand, Odometry, Topics, TrajectorySetpoint
from cufund.geometry import yaw_of

__all__ = ["BumplessTransfer", "ModeReferences"]

_ZERO3 = np.zeros(3)


class ModeReferences:
    """Tracks the flight mode (from ``Topics.FLIGHT_MODE``) and hands the controller its references.

    A reference is taken from its topic only if it was published at or after the latest mode switch; until then
    the controller holds what the vehicle was doing at the switch: in position mode it brakes smoothly from its
    velocity v0 at the switch and then holds the point where it stops (critically damped, time constant
    ``brake_tau``: v_ref = v0 (1 + s/tau) e^(-s/tau), which starts at v0 with zero acceleration and stops
    2 tau v0 further on); in velocity mode it keeps v0; in attitude mode it keeps the controller's last attitude
    and thrust command. The same applies at the start of a run. Controllers additionally fade out any step in
    their own output with :class:`BumplessTransfer`.
    """

    TOPICS = (Topics.TRAJECTORY_SETPOINT, Topics.MANUAL_ATTITUDE_SETPOINT, Topics.FLIGHT_MODE)
    """What it reads (all optional: without a reference the controller holds)."""

    def __init__(
        self,
        mode: FlightMode,
        trajectory_topic: str = Topics.TRAJECTORY_SETPOINT,
        attitude_topic: str = Topics.MANUAL_ATTITUDE_SETPOINT,
        brake_tau: float = 0.25,
    ) -> None:
        self.initial_mode = FlightMode(mode)
        self.brake_tau = float(brake_tau)
        self.trajectory_topic = trajectory_topic
        self.attitude_topic = attitude_topic
        self.reset()

    def reset(self) -> None:
        self.mode = self.initial_mode
        self.switch_t: float | None = None
        self.switched = False
        """True in the first update after a switch (and at the start of a run)."""
        self._hold_traj: TrajectorySetpoint | None = None
        self._hold_att: AttitudeSetpoint | None = None

    def update(self, t: float, state: Odometry, bus: BusView, last_attitude: AttitudeSetpoint | None) -> FlightMode:
        """Reads a pending mode command and, on a switch, captures the hold references."""
        cmd: FlightModeCommand | None = bus.latest(Topics.FLIGHT_MODE)
        self.switched = False
        if self.switch_t is None or (cmd is not None and cmd.t >= self.switch_t and cmd.mode != self.mode):
            if self.switch_t is not None:
                self.mode = cmd.mode  # type: ignore[union-attr]
            self.switch_t = t
            self.switched = True
            yaw = yaw_of(state.q_WB)
            self._hold_traj = TrajectorySetpoint(t, state.p_W.copy(), state.v_W.copy(), _ZERO3, _ZERO3, yaw, 0.0)
            self._hold_att = (
                last_attitude if last_attitude is not None else AttitudeSetpoint(t, state.q_WB.copy(), math.nan)
            )
        return self.mode

    def trajectory(self, t: float, bus: BusView) -> TrajectorySetpoint:
        """The trajectory reference at time ``t`` for position and velocity modes."""
        sp: TrajectorySetpoint | None = bus.latest(self.trajectory_topic)
        if sp is not None and self.switch_t is not None and sp.t >= self.switch_t:
            return sp
        h = self._hold_traj
        assert h is not None and self.switch_t is not None
        if self.mode is not FlightMode.POSITION:
            return h
        tau, s = self.brake_tau, t - self.switch_t
        e = math.exp(-s / tau)
        v0 = h.v_W
        return TrajectorySetpoint(
            t,
            h.p_W + v0 * (2 * tau - (2 * tau + s) * e),
            v0 * ((1 + s / tau) * e),
            v0 * (-(s / tau**2) * e),
            v0 * (-(1 - s / tau) * e / tau**2),
            h.yaw,
            0.0,
        )

    def attitude(self, bus: BusView) -> AttitudeSetpoint:
        """The attitude reference for attitude mode (thrust NaN: hover thrust, chosen by the controller)."""
        sp: AttitudeSetpoint | None = bus.latest(self.attitude_topic)
        if sp is not None and self.switch_t is not None and sp.t >= self.switch_t:
            return sp
        assert self._hold_att is not None
        return self._hold_att


class BumplessTransfer:
    """Fades out the step a mode switch would cause in a controller's output: at a switch, the difference
    between the last command and the new one is stored and added back, decaying as e^(-s / tau)."""

    def __init__(self, tau: float = 0.2) -> None:
        self.tau = float(tau)
        self.reset()

    def reset(self) -> None:
        self._offset: np.ndarray | None = None
        self._t0 = 0.0

    def start(self, t: float, previous: np.ndarray, new: np.ndarray) -> None:
        """At a switch at time ``t``: ``previous`` is the last command, ``new`` the one computed now."""
        self._offset, self._t0 = previous - new, t

    def offset(self, t: float) -> np.ndarray | float:
        """What to add to the command at time ``t``."""
        if self._offset is None:
            return 0.0
        return self._offset * math.exp(-(t - self._t0) / self.tau)

"""Flight-mode switching shared by the controllers: which references are active, and what holds them right
after a switch so that no reference jumps (paper §2.3: attitude, velocity and position modes)."""

from __future__ import annotations

import math

import numpy as np

from ..components import Bus
from ..messages import AttitudeSetpoint, FlightMode, FlightModeCommand, Odometry, Topics, TrajectorySetpoint
from .rotations import yaw_of

__all__ = ["ModeReferences"]

_ZERO3 = np.zeros(3)


class ModeReferences:
    """Tracks the flight mode (from ``Topics.FLIGHT_MODE``) and hands the controller its references.

    A reference is taken from its topic only if it was published at or after the latest mode switch; until then
    the controller holds what the vehicle was doing at the switch: its position (position mode), its velocity
    (velocity mode), or the controller's last attitude and thrust command (attitude mode). The same applies at
    the start of a run.
    """

    def __init__(self, mode: FlightMode, trajectory_topic: str = Topics.TRAJECTORY_SETPOINT,
                 attitude_topic: str = Topics.MANUAL_ATTITUDE_SETPOINT) -> None:
        self.initial_mode = FlightMode(mode)
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

    def update(self, t: float, state: Odometry, bus: Bus, last_attitude: AttitudeSetpoint | None) -> FlightMode:
        """Reads a pending mode command and, on a switch, captures the hold references."""
        cmd: FlightModeCommand | None = bus.get(Topics.FLIGHT_MODE)
        self.switched = False
        if self.switch_t is None or (cmd is not None and cmd.t >= self.switch_t and cmd.mode != self.mode):
            if self.switch_t is not None:
                self.mode = cmd.mode  # type: ignore[union-attr]
            self.switch_t = t
            self.switched = True
            yaw = yaw_of(state.q_WB)
            self._hold_traj = TrajectorySetpoint(t, state.p_W.copy(), state.v_W.copy(), _ZERO3, _ZERO3, yaw, 0.0)
            self._hold_att = last_attitude if last_attitude is not None else AttitudeSetpoint(
                t, state.q_WB.copy(), math.nan)
        return self.mode

    def trajectory(self, bus: Bus) -> TrajectorySetpoint:
        """The trajectory reference for position and velocity modes."""
        sp: TrajectorySetpoint | None = bus.get(self.trajectory_topic)
        if sp is not None and self.switch_t is not None and sp.t >= self.switch_t:
            return sp
        assert self._hold_traj is not None
        return self._hold_traj

    def attitude(self, bus: Bus) -> AttitudeSetpoint:
        """The attitude reference for attitude mode (thrust NaN: hover thrust, chosen by the controller)."""
        sp: AttitudeSetpoint | None = bus.get(self.attitude_topic)
        if sp is not None and self.switch_t is not None and sp.t >= self.switch_t:
            return sp
        assert self._hold_att is not None
        return self._hold_att

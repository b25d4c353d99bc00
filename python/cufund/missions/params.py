"""The commander's parameters (units in the field docs; PX4's names where PX4 has the parameter)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from cufund.core.config import ConfigError, check_at_most

__all__ = ["PX4_NAMES", "CommanderParams"]


@dataclass(frozen=True)
class CommanderParams:
    """How the commander flies its auto modes and when it gives up on a source of commands."""

    rate_hz: float = 250.0
    """Setpoint rate [Hz] (the scenario's ``rates.trajectory_hz`` unless set)."""
    status_hz: float = 10.0
    """VehicleStatus rate [Hz] (also published at every change)."""
    takeoff_altitude: float = 1.5
    """Take-off height above home when the command names none [m] (MIS_TAKEOFF_ALT)."""
    takeoff_speed: float = 0.5
    """Climb speed limit of a take-off [m/s] (MPC_TKO_SPEED)."""
    land_speed: float = 0.3
    """Final descent speed of a landing, from ``land_alt`` down to touchdown [m/s] (MPC_LAND_SPEED)."""
    land_alt: float = 0.3
    """A landing approaches this height above home at go-to speed, then descends at ``land_speed`` [m]
    (MPC_LAND_ALT2)."""
    v_max: float = 1.0
    """Speed limit per axis of go-to, mission and return legs [m/s] (MPC_XY_CRUISE)."""
    a_max: float = 2.0
    """Acceleration limit per axis of auto moves [m/s^2] (MPC_ACC_HOR)."""
    j_max: float = 5.0
    """Jerk limit per axis of auto moves [m/s^3] (MPC_JERK_AUTO)."""
    yaw_rate_max: float = 0.8
    """Peak heading rate of auto turns (go-to and mission yaw) [rad/s]."""
    acceptance_radius: float = 0.15
    """A leg is reached when its reference has arrived and the vehicle is this close [m] (NAV_ACC_RAD)."""
    offboard_timeout_s: float = 0.5
    """Offboard setpoints older than this are stale: the vehicle holds [s] (COM_OF_LOSS_T)."""
    link_loss_timeout_s: float = 5.0
    """After a link loss the vehicle holds, then lands after this long [s] (COM_DL_LOSS_T)."""
    rtl_altitude: float = 2.0
    """Return height above home (at least the current height) [m] (RTL_RETURN_ALT)."""
    auto_disarm_s: float = 10.0
    """Armed on the ground without taking off for this long: disarm [s]; 0 never (COM_DISARM_PRFLT)."""
    brake_tau: float = 0.25
    """Time constant of the critically damped stop when the vehicle holds [s]."""
    touchdown_speed: float = 0.15
    """Touchdown: during the final descent, speed below this [m/s] ..."""
    touchdown_s: float = 0.3
    """... for this long [s] (then the vehicle disarms)."""
    script: tuple = ()
    """``[[t, command], ...]``: commands applied at simulated time t [s] (a scripted flight without a server)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "script":
                continue
            v = getattr(self, f.name)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float))
                or not math.isfinite(v)
                or v < 0
                or (v == 0 and f.name not in ("auto_disarm_s",))
            ):
                raise ConfigError(f"planner.{f.name} must be a finite number > 0, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        check_at_most(self, "planner", rate_hz=1e4, status_hz=1e3)
        from .commands import parse_command

        script = []
        raw = self.script if self.script is not None else ()
        if not isinstance(raw, (list, tuple)):
            raise ConfigError(f"planner.script must be a list of [t, command] pairs, got {raw!r}")
        for i, entry in enumerate(raw):
            if not isinstance(entry, (list, tuple)) or len(entry) != 2:
                raise ConfigError(f"planner.script[{i}] must be [t, command], got {entry!r}")
            t, cmd = entry
            if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) or t < 0:
                raise ConfigError(f"planner.script[{i}] time must be a finite number >= 0 [s], got {t!r}")
            try:
                script.append((float(t), parse_command(cmd)))
            except ValueError as e:
                raise ConfigError(f"planner.script[{i}]: {e}") from None
        object.__setattr__(self, "script", tuple(sorted(script, key=lambda e: e[0])))


PX4_NAMES = {
    "MIS_TAKEOFF_ALT": "takeoff_altitude",
    "MPC_TKO_SPEED": "takeoff_speed",
    "MPC_LAND_SPEED": "land_speed",
    "MPC_LAND_ALT2": "land_alt",
    "MPC_XY_CRUISE": "v_max",
    "MPC_ACC_HOR": "a_max",
    "MPC_JERK_AUTO": "j_max",
    "NAV_ACC_RAD": "acceptance_radius",
    "COM_OF_LOSS_T": "offboard_timeout_s",
    "COM_DL_LOSS_T": "link_loss_timeout_s",
    "RTL_RETURN_ALT": "rtl_altitude",
    "COM_DISARM_PRFLT": "auto_disarm_s",
}
"""PX4 parameter name -> CommanderParams field."""


def settable() -> list[str]:
    return [f.name for f in fields(CommanderParams) if f.name not in ("script", "rate_hz", "status_hz")]


def field_of(name: str) -> str | None:
    """The CommanderParams field a parameter name (own or PX4's) refers to."""
    if name in PX4_NAMES:
        return PX4_NAMES[name]
    return name if name in settable() else None


def as_dict(p: CommanderParams) -> dict[str, Any]:
    """The settable parameters, under PX4's name where PX4 has one."""
    back = {v: k for k, v in PX4_NAMES.items()}
    return {back.get(n, n): getattr(p, n) for n in settable()}

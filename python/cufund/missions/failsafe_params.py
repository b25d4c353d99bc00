"""The failsafe supervisor's parameters: the scenario's ``failsafe:`` section, under PX4's parameter names where
PX4 has the parameter (units in the field docs; cufund's own names are marked so).

``failsafe:`` absent or ``{}``: the defaults below (the supervisor runs, as PX4's failsafes do; the geofence is
off until given a distance, the battery failsafes act only when a battery is configured); ``failsafe: off``
(``false``): no supervisor at all.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from cufund.core.config import ConfigError, from_dict

__all__ = ["BAT_ACTIONS", "GF_ACTIONS", "FailsafeParams", "parse_failsafe"]

BAT_ACTIONS = {
    0: "warning",
    1: "return at low, land at critical",
    2: "land at critical",
    3: "return at critical, land at emergency",
}
"""COM_LOW_BAT_ACT: what the battery failsafe does (PX4's 0, 2 and 3; 1 is the issue's low -> return, critical ->
land, which older PX4 versions called "Return mode")."""

GF_ACTIONS = {0: "none", 1: "warning", 2: "hold", 3: "return", 4: "terminate", 5: "land"}
"""GF_ACTION: PX4's geofence actions (4, terminate, disarms: the rotors stop)."""


@dataclass(frozen=True)
class FailsafeParams:
    """When the flight stack's failsafes fire and what they do (see docs/guides/failsafes.md)."""

    rate_hz: float = 20.0
    """How often the supervisor checks [Hz] (cufund); the motor-failure detector takes the rates since its last check, at up to 100 Hz."""
    BAT_LOW_THR: float = 0.15
    """Low battery: remaining charge at or below this fraction [0..1] (PX4 BAT_LOW_THR)."""
    BAT_CRIT_THR: float = 0.07
    """Critical battery [0..1] (PX4 BAT_CRIT_THR)."""
    BAT_EMERGEN_THR: float = 0.05
    """Emergency battery [0..1] (PX4 BAT_EMERGEN_THR): COM_LOW_BAT_ACT 3 lands here."""
    COM_LOW_BAT_ACT: int = 1
    """Battery failsafe action (:data:`BAT_ACTIONS`): 0 warn only, 1 return at low and land at critical (default),
    2 land at critical, 3 return at critical and land at emergency (PX4 COM_LOW_BAT_ACT)."""
    COM_POS_FS_DELAY: float = 1.0
    """The state estimate must stay unhealthy (LIO diagnostics, LiDAR silence, a GPS-only estimate without GPS)
    this long before the estimator failsafe holds [s] (PX4 COM_POS_FS_DELAY)."""
    COM_FAIL_ACT_T: float = 5.0
    """Hold this long after the estimator failsafe fired, then land unless the estimate recovered [s] (PX4
    COM_FAIL_ACT_T, PX4's default; the LIO's recoverable spells, re-estimating its biases, last up to ~3 s)."""
    EST_SILENCE_T: float = 0.35
    """No estimator diagnostics (one per LiDAR frame) for this long is an unhealthy estimate [s] (cufund; the tunnel
    mission's own ``lidar_silence_s`` applies where it flies)."""
    GPS_LOSS_T: float = 0.5
    """No GPS fix (fix_type >= 3) for this long is a GPS loss [s] (cufund; PX4's EKF2 times the GPS out itself)."""
    GF_ACTION: int = 2
    """Geofence breach action (:data:`GF_ACTIONS`; PX4 GF_ACTION, default hold)."""
    GF_MAX_HOR_DIST: float = 0.0
    """Geofence: largest horizontal distance from home [m]; 0: no horizontal limit (PX4 GF_MAX_HOR_DIST)."""
    GF_MAX_VER_DIST: float = 0.0
    """Geofence: largest height above home [m]; 0: no vertical limit (PX4 GF_MAX_VER_DIST)."""
    RTL_RETURN_ALT: float = 1.5
    """A return climbs to at least this height above home before flying home [m] (PX4 RTL_RETURN_ALT; under a
    commander its own ``rtl_altitude`` applies)."""
    MPC_LAND_SPEED: float = 0.3
    """Failsafe landing: speed of the final descent [m/s] (PX4 MPC_LAND_SPEED)."""
    MPC_XY_CRUISE: float = 1.0
    """Failsafe return: speed limit per axis [m/s] (PX4 MPC_XY_CRUISE)."""
    FD_FAIL_R: float = 60.0
    """Attitude failure: roll beyond this [deg] for FD_FAIL_R_TTRI disarms (flight termination); 0: off (PX4
    FD_FAIL_R)."""
    FD_FAIL_P: float = 60.0
    """Attitude failure: pitch beyond this [deg] for FD_FAIL_P_TTRI disarms; 0: off (PX4 FD_FAIL_P)."""
    FD_FAIL_R_TTRI: float = 0.3
    """[s] (PX4 FD_FAIL_R_TTRI)."""
    FD_FAIL_P_TTRI: float = 0.3
    """[s] (PX4 FD_FAIL_P_TTRI)."""
    FD_ACT_EN: bool = True
    """Motor failure detection from the rate residuals (PX4 FD_ACT_EN enables its actuator failure check)."""
    FD_ACT_RES_THR: float = 0.5
    """Motor failure: the unexplained body torque (the momentum observer's residual) exceeds this fraction of one
    rotor's hover torque about the roll/pitch axes, thrust x arm [-] (cufund) ..."""
    FD_ACT_TTRI: float = 0.15
    """... for this long [s] (cufund); then the vehicle lands at once."""
    FD_ACT_BANDWIDTH: float = 15.0
    """The residual observer's bandwidth [rad/s] (cufund): higher detects sooner, lower rejects IMU noise."""

    _REAL = (
        "rate_hz",
        "BAT_LOW_THR",
        "BAT_CRIT_THR",
        "BAT_EMERGEN_THR",
        "COM_POS_FS_DELAY",
        "COM_FAIL_ACT_T",
        "EST_SILENCE_T",
        "GPS_LOSS_T",
        "GF_MAX_HOR_DIST",
        "GF_MAX_VER_DIST",
        "RTL_RETURN_ALT",
        "MPC_LAND_SPEED",
        "MPC_XY_CRUISE",
        "FD_FAIL_R",
        "FD_FAIL_P",
        "FD_FAIL_R_TTRI",
        "FD_FAIL_P_TTRI",
        "FD_ACT_RES_THR",
        "FD_ACT_TTRI",
        "FD_ACT_BANDWIDTH",
    )

    def __post_init__(self) -> None:
        for name in self._REAL:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"failsafe.{name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        for name in ("rate_hz", "MPC_LAND_SPEED", "MPC_XY_CRUISE", "FD_ACT_RES_THR", "FD_ACT_BANDWIDTH"):
            if getattr(self, name) == 0:
                raise ConfigError(f"failsafe.{name} must be > 0, got 0")
        if self.rate_hz > 1000:
            raise ConfigError(f"failsafe.rate_hz must be at most 1000 Hz, got {self.rate_hz!r}")
        for name in ("BAT_LOW_THR", "BAT_CRIT_THR", "BAT_EMERGEN_THR"):
            if getattr(self, name) > 1:
                raise ConfigError(
                    f"failsafe.{name} must be a fraction of the charge in [0, 1], got {getattr(self, name)!r}"
                )
        if not self.BAT_LOW_THR >= self.BAT_CRIT_THR >= self.BAT_EMERGEN_THR:
            raise ConfigError(
                "failsafe: BAT_LOW_THR >= BAT_CRIT_THR >= BAT_EMERGEN_THR expected, got "
                f"{self.BAT_LOW_THR}, {self.BAT_CRIT_THR}, {self.BAT_EMERGEN_THR}"
            )
        for name in ("FD_FAIL_R", "FD_FAIL_P"):
            if getattr(self, name) > 180:
                raise ConfigError(
                    f"failsafe.{name} must be an angle in [0, 180] deg (0: off), got {getattr(self, name)!r}"
                )
        for name, table in (("COM_LOW_BAT_ACT", BAT_ACTIONS), ("GF_ACTION", GF_ACTIONS)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v not in table:
                options = ", ".join(f"{k} ({d})" for k, d in table.items())
                raise ConfigError(f"failsafe.{name} must be one of {options}; got {v!r}")
        if not isinstance(self.FD_ACT_EN, bool):
            if isinstance(self.FD_ACT_EN, int) and self.FD_ACT_EN in (0, 1):
                object.__setattr__(self, "FD_ACT_EN", bool(self.FD_ACT_EN))
            else:
                raise ConfigError(f"failsafe.FD_ACT_EN must be true or false (or 1/0), got {self.FD_ACT_EN!r}")

    def to_data(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def parse_failsafe(value: Any) -> FailsafeParams | bool:
    """The ``failsafe:`` key: None/absent/true -> the defaults, ``off``/``false`` -> False (no supervisor), a mapping
    of :class:`FailsafeParams` fields -> those."""
    if value is None or value is True:
        return FailsafeParams()
    if value is False or (isinstance(value, str) and value.lower() in ("off", "false")):
        return False
    if isinstance(value, FailsafeParams):
        return value
    if isinstance(value, dict):
        return from_dict(FailsafeParams, value, "failsafe")
    raise ConfigError(
        f"failsafe must be a mapping of PX4-named parameters (e.g. {{GF_MAX_HOR_DIST: 5}}) or off, got {value!r}"
    )

"""GNSS faults: a dropout (no fix), a jump (a position offset) and a drift (a slowly growing offset: spoofing).

Each acts on the fixes by their measurement time ``t`` (a fix measured in the fault's window is affected, whenever
the receiver's latency delivers it). Offsets are east-north-up [m], applied to the fix's position in the local
frame of the receiver's ``home`` and converted back to latitude, longitude and height (WGS-84).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.messages import GpsFix

from ..geodesy import enu_to_lla, lla_to_enu
from .base import FaultRun, SensorFault
from .common import active, check_duration, check_sensor, check_time, check_vector

__all__ = ["GpsDrift", "GpsDropout", "GpsJump", "offset_fix"]


def offset_fix(fix: GpsFix, dp_W: np.ndarray, dv_W: np.ndarray | None, home: Any) -> GpsFix:
    """``fix`` moved by ``dp_W`` (ENU [m], about ``home``) and its velocity by ``dv_W`` [m/s]; a no-fix stays."""
    if fix.fix_type == 0:
        return fix
    p = lla_to_enu(np.array([fix.latitude_deg, fix.longitude_deg, fix.altitude_m]), home) + dp_W
    lat, lon, alt = enu_to_lla(p, home)
    v = fix.v_W + dv_W if dv_W is not None else fix.v_W
    return GpsFix(fix.t, float(lat), float(lon), float(alt), v, fix.fix_type, fix.satellites, fix.eph, fix.epv)


@dataclass(frozen=True)
class GpsDropout(SensorFault):
    """No fix for ``duration`` s: the fixes measured in [t_start, t_start + duration) arrive as no-fix reports
    (``fix_type`` 0, no satellites, NaN position and velocity, infinite accuracy), as the receiver reports an
    outage."""

    t_start: float
    """Start of the outage (measurement time) [s]."""
    duration: float = 5.0
    """Length of the outage [s]."""
    sensor: str = ""
    """The receiver's name under ``sensors`` ('' : the only GPS)."""

    kind = "gps_dropout"
    sensor_type = "gps"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        object.__setattr__(self, "duration", check_time(f"{w}.duration", self.duration, positive=True))
        check_sensor(f"{w}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if not active(msg.t, self.t_start, self.duration):
            return msg
        return GpsFix(msg.t, math.nan, math.nan, math.nan, np.full(3, math.nan), 0, 0, math.inf, math.inf)


@dataclass(frozen=True)
class GpsJump(SensorFault):
    """The fixes jump by ``offset_m`` (east, north, up) from ``t_start`` (for ``duration`` s, or for good): a
    multipath or re-acquisition jump. Velocity unchanged."""

    t_start: float
    """When the position jumps (measurement time) [s]."""
    offset_m: tuple[float, float, float]
    """Position offset, ENU [m] (not all zero; at most 1e4 per axis)."""
    duration: float | None = None
    """How long the offset lasts [s]; null: to the end of the run."""
    sensor: str = ""
    """The receiver's name under ``sensors`` ('' : the only GPS)."""

    kind = "gps_jump"
    sensor_type = "gps"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        object.__setattr__(self, "offset_m", check_vector(f"{w}.offset_m", self.offset_m, 1e4, " [m]", nonzero=True))
        object.__setattr__(self, "duration", check_duration(f"{w}.duration", self.duration))
        check_sensor(f"{w}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if not active(msg.t, self.t_start, self.duration):
            return msg
        return offset_fix(msg, np.asarray(self.offset_m), None, run.sensor_params.home)


@dataclass(frozen=True)
class GpsDrift(SensorFault):
    """A slow drag-off (spoofing): from ``t_start`` the fixes' position is off by ``rate_mps (t - t_start)`` and
    their velocity by ``rate_mps``, consistently (so a velocity check alone does not see it); for ``duration`` s
    (then the fixes are true again) or for good."""

    t_start: float
    """When the drift starts (measurement time) [s]."""
    rate_mps: tuple[float, float, float]
    """Drift velocity, ENU [m/s] (not all zero; at most 100 per axis)."""
    duration: float | None = None
    """How long the spoofing lasts [s]; null: to the end of the run."""
    sensor: str = ""
    """The receiver's name under ``sensors`` ('' : the only GPS)."""

    kind = "gps_drift"
    sensor_type = "gps"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        object.__setattr__(
            self, "rate_mps", check_vector(f"{w}.rate_mps", self.rate_mps, 100.0, " [m/s]", nonzero=True)
        )
        object.__setattr__(self, "duration", check_duration(f"{w}.duration", self.duration))
        check_sensor(f"{w}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if not active(msg.t, self.t_start, self.duration):
            return msg
        rate = np.asarray(self.rate_mps)
        return offset_fix(msg, rate * (msg.t - self.t_start), rate, run.sensor_params.home)

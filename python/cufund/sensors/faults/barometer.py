"""Barometer fault: a step in the reading (a pressure disturbance, e.g. the prop wash or a door opening, or a
sensor offset jump)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cufund.core.config import ConfigError
from cufund.core.messages import AirPressure

from ..barometer import isa_altitude, isa_pressure
from .base import FaultRun, SensorFault
from .common import active, check_duration, check_real, check_sensor, check_time

__all__ = ["BaroStep"]


@dataclass(frozen=True)
class BaroStep(SensorFault):
    """From ``t_start`` (for ``duration`` s, or for good) the barometer reads off by a step, given as one of:
    ``offset_m``, the reported altitude is ``offset_m`` higher and the pressure the standard atmosphere's at that
    altitude; ``offset_pa``, the pressure is ``offset_pa`` higher and the altitude the one it inverts to (a
    pressure rise reads lower)."""

    t_start: float
    """When the step happens (measurement stamp) [s]."""
    offset_m: float | None = None
    """Altitude step [m], in [-1000, 1000]."""
    offset_pa: float | None = None
    """Or pressure step [Pa], in [-10000, 10000]."""
    duration: float | None = None
    """Length of the step [s]; null: to the end of the run."""
    sensor: str = ""
    """The barometer's name under ``sensors`` ('' : the only one)."""

    kind = "baro_step"
    sensor_type = "barometer"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        if (self.offset_m is None) == (self.offset_pa is None):
            raise ConfigError(
                f"{w} needs exactly one of offset_m [m] and offset_pa [Pa], "
                f"got offset_m={self.offset_m!r}, offset_pa={self.offset_pa!r}"
            )
        if self.offset_m is not None:
            object.__setattr__(self, "offset_m", check_real(f"{w}.offset_m", self.offset_m, -1e3, 1e3, " [m]"))
        else:
            object.__setattr__(self, "offset_pa", check_real(f"{w}.offset_pa", self.offset_pa, -1e4, 1e4, " [Pa]"))
        object.__setattr__(self, "duration", check_duration(f"{w}.duration", self.duration))
        check_sensor(f"{w}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if not active(msg.t, self.t_start, self.duration):
            return msg
        p = run.sensor_params  # BarometerParams: the atmosphere the sensor's altitude comes from
        slp, slt, home = p.sea_level_pressure_pa, p.sea_level_temperature_k, p.home_altitude_m
        if self.offset_m is not None:
            altitude = msg.altitude_m + self.offset_m
            pressure = float(isa_pressure(home + altitude, slp, slt))
        else:
            assert self.offset_pa is not None  # __post_init__ holds one of the two
            pressure = msg.pressure_pa + self.offset_pa
            altitude = float(isa_altitude(pressure, slp, slt)) - home
        return AirPressure(msg.t, pressure, altitude, msg.temperature_k)

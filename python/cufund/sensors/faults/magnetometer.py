"""Magnetometer fault: a disturbance field (a magnetised structure, a current nearby) added to the readings."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError
from cufund.core.messages import MagneticField

from .base import FaultRun, SensorFault
from .common import active, check_duration, check_real, check_sensor, check_time, check_vector, unit_vector

__all__ = ["MagDisturbance"]


@dataclass(frozen=True)
class MagDisturbance(SensorFault):
    """From ``t_start`` (for ``duration`` s, or for good) the magnetometer reads an extra field along its (the
    body's) axes: ``field_T`` [T], or a field of ``magnitude_T`` [T] in a direction drawn uniformly on the sphere
    from the fault's seeded stream (one of the two). Earth's field is 25-65 uT; steel or a cable next to the sensor
    adds tens to hundreds of uT."""

    t_start: float
    """Start of the disturbance (measurement stamp) [s]."""
    field_T: tuple[float, float, float] | None = None
    """The added field along the sensor's axes [T] (at most 0.01 T per axis)."""
    magnitude_T: float | None = None
    """Or its magnitude [T], in (0, 0.01], direction drawn from the seeded stream."""
    duration: float | None = None
    """Length of the disturbance [s]; null: to the end of the run."""
    sensor: str = ""
    """The magnetometer's name under ``sensors`` ('' : the only one)."""

    kind = "mag_disturbance"
    sensor_type = "magnetometer"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        if (self.field_T is None) == (self.magnitude_T is None):
            raise ConfigError(
                f"{w} needs exactly one of field_T (a vector [T]) and magnitude_T (a number [T]), "
                f"got field_T={self.field_T!r}, magnitude_T={self.magnitude_T!r}"
            )
        if self.field_T is not None:
            object.__setattr__(self, "field_T", check_vector(f"{w}.field_T", self.field_T, 0.01, " [T]"))
        else:
            object.__setattr__(
                self, "magnitude_T", check_real(f"{w}.magnitude_T", self.magnitude_T, 0.0, 0.01, " [T]", True)
            )
        object.__setattr__(self, "duration", check_duration(f"{w}.duration", self.duration))
        check_sensor(f"{w}.sensor", self.sensor)

    def start(self, run: FaultRun) -> np.ndarray:
        if self.field_T is not None:
            return np.asarray(self.field_T)
        assert self.magnitude_T is not None  # __post_init__ holds one of the two
        return self.magnitude_T * unit_vector(run.rng)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if not active(msg.t, self.t_start, self.duration):
            return msg
        return MagneticField(msg.t, msg.m_B + run.state)

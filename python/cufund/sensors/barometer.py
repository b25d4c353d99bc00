"""Barometer: International Standard Atmosphere pressure at the vehicle's altitude, with drift and noise.

ISA troposphere (ISO 2533): T(h) = T0 - L h,  p(h) = p0 (T(h) / T0)^(g0 M / (R* L)), with L = 0.0065 K/m,
g0 = 9.80665 m/s^2, M = 0.0289644 kg/mol and the standard's own R* = 8.31432 J/(mol K). The sensor reports
pressure [Pa] with the error model of :mod:`cufund.sensors.noise` (drift = bias random walk) and the altitude the ISA inverts from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, check_at_most, check_real_fields, nested
from cufund.core.messages import AirPressure, Odometry, Topics

from .model_sensor import ModelSensor
from .noise import ErrorProcess, NoiseSpec, real_fields

__all__ = ["isa_pressure", "isa_altitude", "BarometerParams", "BarometerModel", "BarometerSensor", "BAROMETER_PRESETS"]

P0 = 101325.0  # [Pa]
T0 = 288.15  # [K]
LAPSE = 0.0065  # [K/m]
EXPONENT = 9.80665 * 0.0289644 / (8.31432 * LAPSE)  # g0 M / (R* L) = 5.255876 with ISO 2533's R*


def _real(x: float | np.ndarray) -> float | np.ndarray:
    """A Python number stays one (the fast per-sample path); anything else becomes a float array."""
    return x if isinstance(x, (float, int)) else np.asarray(x, float)


def isa_pressure(
    altitude_m: float | np.ndarray, sea_level_pressure: float = P0, sea_level_temperature: float = T0
) -> float | np.ndarray:
    """Static pressure [Pa] at geopotential altitude [m] above mean sea level."""
    return sea_level_pressure * (1.0 - LAPSE * _real(altitude_m) / sea_level_temperature) ** EXPONENT


def isa_altitude(
    pressure_pa: float | np.ndarray, sea_level_pressure: float = P0, sea_level_temperature: float = T0
) -> float | np.ndarray:
    """Altitude [m] above mean sea level at which the ISA has ``pressure_pa``."""
    return sea_level_temperature / LAPSE * (1.0 - (_real(pressure_pa) / sea_level_pressure) ** (1.0 / EXPONENT))


@dataclass(frozen=True)
class BarometerParams:
    """A barometer and the day's atmosphere. The world frame's z = 0 lies ``home_altitude_m`` above sea level."""

    rate_hz: float = 50.0
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    """Pressure errors [Pa/sqrt(Hz)], drift [Pa/s/sqrt(Hz)], turn-on offset [Pa]."""
    home_altitude_m: float = 0.0
    sea_level_pressure_pa: float = P0
    sea_level_temperature_k: float = T0
    name: str = "ideal"

    def __post_init__(self) -> None:
        real_fields(self, "BarometerParams")
        check_real_fields(self, "BarometerParams", positive=True, unit=" [Hz]", names=("rate_hz",))
        check_at_most(self, "BarometerParams", rate_hz=1e3)
        object.__setattr__(self, "noise", nested(NoiseSpec, self.noise, "BarometerParams.noise"))
        self.noise.per_axis(1)
        if not (math.isfinite(self.home_altitude_m) and -500 <= self.home_altitude_m <= 10000):
            raise ConfigError(f"home_altitude_m must be in [-500, 10000] [m], got {self.home_altitude_m!r}")
        if not (math.isfinite(self.sea_level_pressure_pa) and 80000 <= self.sea_level_pressure_pa <= 110000):
            raise ConfigError(
                f"sea_level_pressure_pa must be in [80000, 110000] [Pa], got {self.sea_level_pressure_pa!r}"
            )
        if not (math.isfinite(self.sea_level_temperature_k) and 200 <= self.sea_level_temperature_k <= 340):
            raise ConfigError(
                f"sea_level_temperature_k must be in [200, 340] [K], got {self.sea_level_temperature_k!r}"
            )


#: TE Connectivity MS5611-01BA03 datasheet: RMS resolution 0.012 mbar (1.2 Pa) at OSR 4096, one
#: conversion per 9.04 ms (max); run at 50 Hz here, so the density is 1.2 Pa * sqrt(1 / 50 Hz).
#: Drift 0.5 Pa/s/sqrt(Hz) (about 5 Pa, 0.4 m, over 100 s) stands for the slow thermal drift the datasheet
#: does not quantify; turn-on offset 100 Pa (its absolute accuracy is +-1.5 mbar).
BAROMETER_PRESETS = {
    "ms5611": lambda: BarometerParams(
        name="ms5611", rate_hz=50.0, noise=NoiseSpec(1.2 * math.sqrt(1 / 50.0), 0.5, 100.0)
    ),
    "ideal": lambda: BarometerParams(),
}


class BarometerModel:
    """Pressure [Pa] and ISA altitude [m, world z] samples for true heights z_W [m], from one seeded stream."""

    def __init__(self, params: BarometerParams, seed: int = 0) -> None:
        self.params = params
        self._errors = ErrorProcess([(params.noise, 1)], 1.0 / params.rate_hz, seed)

    def reset(self) -> None:
        self._errors.reset()

    def temperature_k(self, z_W: float | np.ndarray) -> float | np.ndarray:
        """Air temperature [K] at world heights z_W [m] (ISA lapse)."""
        p = self.params
        return p.sea_level_temperature_k - LAPSE * (p.home_altitude_m + _real(z_W))

    def measure(self, z_W: float | np.ndarray) -> tuple[Any, Any]:
        """(pressure [Pa], altitude above home [m]) for heights z_W (K,) or a scalar."""
        p = self.params
        if np.ndim(z_W) == 0:  # the per-tick path, in scalar arithmetic
            z0 = float(z_W)
            if not math.isfinite(z0):
                raise ValueError(f"z_W must be finite with shape () or (K,), got {z_W!r}")
            pressure = isa_pressure(p.home_altitude_m + z0, p.sea_level_pressure_pa, p.sea_level_temperature_k)
            pressure += float(self._errors.sample_one()[0])
            altitude = isa_altitude(pressure, p.sea_level_pressure_pa, p.sea_level_temperature_k)
            return pressure, altitude - p.home_altitude_m
        z = np.atleast_1d(np.asarray(z_W, dtype=float))
        if z.ndim != 1 or not np.all(np.isfinite(z)):
            raise ValueError(f"z_W must be finite with shape () or (K,), got {np.shape(z_W)}")
        pressure = isa_pressure(p.home_altitude_m + z, p.sea_level_pressure_pa, p.sea_level_temperature_k)
        pressure = pressure + self._errors.sample(z.shape[0])[:, 0]
        altitude = isa_altitude(pressure, p.sea_level_pressure_pa, p.sea_level_temperature_k) - p.home_altitude_m
        return pressure, altitude


class BarometerSensor(ModelSensor):
    """Publishes :class:`~cufund.core.messages.AirPressure` samples at the sensor's rate."""

    name = "barometer"

    def __init__(self, params: BarometerParams, seed: int = 0, topic: str = Topics.BAROMETER) -> None:
        super().__init__(BarometerModel(params, seed), params.rate_hz, topic)

    def measure(self, t: float, truth: Odometry) -> AirPressure:
        z = float(truth.p_W[2])
        pressure, altitude = self.model.measure(z)
        return AirPressure(t, pressure, altitude, self.model.temperature_k(z))

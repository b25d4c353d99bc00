"""What every fault shares: the validators of its fields, and the time window it acts in."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, vector3

__all__ = ["active", "check_duration", "check_real", "check_sensor", "check_time", "check_vector"]


def check_time(where: str, value: Any, positive: bool = False) -> float:
    """A time [s] in [0, 1e6] ((0, 1e6] with ``positive``), else a ConfigError naming ``where``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value < 0
        or (positive and value == 0)
        or value > 1e6
    ):
        raise ConfigError(f"{where} must be a number of seconds in {'(0' if positive else '[0'}, 1e6], got {value!r}")
    return float(value)


def check_duration(where: str, value: Any) -> float | None:
    """A fault's ``duration`` [s]: null (to the end of the run) or a time in (0, 1e6]."""
    return None if value is None else check_time(where, value, positive=True)


def check_sensor(where: str, value: Any) -> str:
    if not isinstance(value, str) or (value and not value.isidentifier()):
        raise ConfigError(f"{where} must be a sensor name under sensors (or '' for the only one), got {value!r}")
    return value


def check_real(where: str, value: Any, lo: float, hi: float, unit: str, lo_open: bool = False) -> float:
    """A real number in [lo, hi] ((lo, hi] with ``lo_open``), else a ConfigError naming ``where``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not (lo < value if lo_open else lo <= value)
        or value > hi
    ):
        raise ConfigError(f"{where} must be a number in {'(' if lo_open else '['}{lo:g}, {hi:g}]{unit}, got {value!r}")
    return float(value)


def check_vector(where: str, value: Any, bound: float, unit: str, nonzero: bool = False) -> tuple[float, float, float]:
    """3 finite numbers, each of magnitude at most ``bound`` (``nonzero``: not all zero), else a ConfigError naming
    ``where``."""
    v = vector3(where, value, unit, finite=True)
    if max(map(abs, v)) > bound:
        raise ConfigError(f"{where} must be at most {bound:g}{unit} per axis, got {list(v)}")
    if nonzero and not any(v):
        raise ConfigError(f"{where} must not be all zero (a fault that changes nothing){unit}, got {list(v)}")
    return v


def active(t: float, t_start: float, duration: float | None) -> bool:
    """Whether a fault starting at ``t_start`` for ``duration`` (None: for good) acts at time ``t``."""
    return t >= t_start and (duration is None or t < t_start + duration)


def unit_vector(rng: np.random.Generator) -> np.ndarray:
    """A direction uniform on the sphere."""
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)

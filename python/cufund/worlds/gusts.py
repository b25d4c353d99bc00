"""Discrete gusts: the 1-cosine shape (docs/guides/atmosphere.md).

A gust of amplitude ``A`` [m/s] starting at ``t_start`` and lasting ``duration`` ``T`` [s] adds, horizontally along
``direction_deg`` (the direction it blows towards, counter-clockwise from +x),

    v(t) = A / 2 * (1 - cos(2 pi (t - t_start) / T))   for t_start <= t <= t_start + T, else 0

(the full 1-cosine: it rises to A at mid-gust and falls back to zero). The plant evaluates it in C++
(``cpp/dynamics/atmosphere.cpp``) at each atmosphere update.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cufund import _core
from cufund.core.config import ConfigError, check_real_fields, from_dict

__all__ = ["GustConfig", "parse_gusts"]


@dataclass(frozen=True)
class GustConfig:
    """One 1-cosine gust."""

    t_start: float
    """When it starts [s]."""
    duration: float
    """How long it lasts [s], > 0."""
    amplitude_mps: float
    """Its peak speed [m/s], |.| <= 100."""
    direction_deg: float = 0.0
    """The direction it blows towards, counter-clockwise from +x (east) [deg]."""

    def __post_init__(self) -> None:
        check_real_fields(self, "atmosphere.gusts", names=("t_start", "amplitude_mps", "direction_deg"))
        check_real_fields(self, "atmosphere.gusts", positive=True, unit=" [s]", names=("duration",))
        if abs(self.amplitude_mps) > 100.0:
            raise ConfigError(f"atmosphere.gusts.amplitude_mps must be within +-100 m/s, got {self.amplitude_mps!r}")

    def to_core(self) -> Any:
        g = _core.dynamics.GustEvent()
        g.t_start, g.duration, g.amplitude = self.t_start, self.duration, self.amplitude_mps
        g.direction = math.radians(self.direction_deg)
        return g


def parse_gusts(value: Any) -> tuple[GustConfig, ...]:
    """A list of gust mappings (or one mapping, or null) as :class:`GustConfig` s."""
    if value is None:
        return ()
    if isinstance(value, GustConfig):
        return (value,)
    if isinstance(value, dict):
        value = [value]
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"atmosphere.gusts must be a list of gusts, got {type(value).__name__}")
    return tuple(
        g if isinstance(g, GustConfig) else from_dict(GustConfig, g, f"atmosphere.gusts[{i}]")
        for i, g in enumerate(value)
    )

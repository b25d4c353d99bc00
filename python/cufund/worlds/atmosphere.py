"""The scenario's ``atmosphere:`` (docs/guides/atmosphere.md): its configuration and the plant's wind from it.

``atmosphere: {kind: calm | constant | dryden, wind_20ft_mps, direction_deg, shear, gusts, grid_file, seed,
update_hz, min_airspeed_mps}``, or just ``atmosphere: calm``. Off (null) by default: the plant then flies in still
air and every existing run is unchanged. The wind is

    mean(h) along direction_deg  +  grid(p)  +  Dryden turbulence (kind dryden)  +  1-cosine gusts

evaluated in C++ for the vehicle's position and velocity once per ``1 / update_hz`` of simulated time and held in
between (``cpp/dynamics/atmosphere.cpp``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cufund import _core
from cufund.core.config import ConfigError, check_real_fields, from_dict

from .gusts import GustConfig, parse_gusts
from .wind_grid import load_wind_grid

__all__ = ["KINDS", "SHEARS", "AtmosphereConfig", "ShearConfig", "apply_atmosphere"]

KINDS = ("calm", "constant", "dryden")
SHEARS = ("none", "log", "power")
_SHEAR_CORE = {"none": "NONE", "log": "LOG", "power": "POWER"}


@dataclass(frozen=True)
class ShearConfig:
    """The mean wind's profile with height h above z = 0, from the 20 ft (6.096 m) value ``W20``.

    ``log`` (MIL-F-8785C): ``W20 ln(h / z0) / ln(6.096 / z0)``, zero below ``z0``; ``power``: ``W20 (h / 6.096)^a``;
    ``none``: ``W20`` at every height."""

    kind: str = "log"
    z0_m: float = 0.0457
    """Roughness length of the log law [m] (MIL-F-8785C: 0.15 ft for terminal flight phases)."""
    exponent: float = 1.0 / 7.0
    """Exponent of the power law (1/7: open terrain)."""

    def __post_init__(self) -> None:
        if self.kind not in SHEARS:
            raise ConfigError(f"atmosphere.shear.kind must be one of {', '.join(SHEARS)}, got {self.kind!r}")
        check_real_fields(self, "atmosphere.shear", names=("z0_m", "exponent"))
        if not 0.0 < self.z0_m < 6.096:
            raise ConfigError(f"atmosphere.shear.z0_m must be in (0, 6.096) [m], got {self.z0_m!r}")
        if not 0.0 <= self.exponent <= 1.0:
            raise ConfigError(f"atmosphere.shear.exponent must be in [0, 1], got {self.exponent!r}")

    @staticmethod
    def parse(value: Any) -> ShearConfig:
        if isinstance(value, ShearConfig):
            return value
        if value is None:
            return ShearConfig()
        if isinstance(value, str):
            return ShearConfig(kind=value)
        return from_dict(ShearConfig, value, "atmosphere.shear")


@dataclass(frozen=True)
class AtmosphereConfig:
    """The air the vehicle flies in."""

    kind: str = "calm"
    """``calm`` (no mean wind or turbulence; gusts and a grid still apply), ``constant`` (the mean wind with its
    shear), ``dryden`` (the mean wind plus Dryden turbulence)."""
    wind_20ft_mps: float = 0.0
    """Mean wind speed at 20 ft (6.096 m) [m/s], in [0, 100]; it sets the turbulence intensity (sigma_w = 0.1 W20)."""
    direction_deg: float = 0.0
    """The direction the mean wind blows towards, counter-clockwise from +x (east) [deg] (90: towards +y)."""
    shear: ShearConfig = field(default_factory=ShearConfig)
    """``log`` (default), ``power``, ``none``, or ``{kind: log, z0_m: ...}`` / ``{kind: power, exponent: ...}``."""
    gusts: tuple[GustConfig, ...] = ()
    """1-cosine gusts: ``[{t_start, duration, amplitude_mps, direction_deg}, ...]``."""
    grid_file: str | None = None
    """A wind grid ``.npz`` (:mod:`cufund.worlds.wind_grid`) added to the mean wind; relative to the scenario file."""
    seed: int | None = None
    """The turbulence's seed; null: drawn from the scenario's seed (``seed_for('atmosphere')``)."""
    update_hz: float = 200.0
    """How often the wind is re-evaluated [Hz] (held in between), in [1, 10000]."""
    min_airspeed_mps: float = 1.0
    """Floor of the airspeed V that turns the turbulence's spatial spectrum into time (a hovering vehicle in calm
    air would otherwise see frozen turbulence) [m/s], > 0."""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ConfigError(f"atmosphere.kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        check_real_fields(self, "atmosphere", names=("wind_20ft_mps", "direction_deg"))
        check_real_fields(self, "atmosphere", positive=True, names=("update_hz", "min_airspeed_mps"))
        if not 0.0 <= self.wind_20ft_mps <= 100.0:
            raise ConfigError(f"atmosphere.wind_20ft_mps must be in [0, 100] [m/s], got {self.wind_20ft_mps!r}")
        if self.kind == "calm" and self.wind_20ft_mps != 0.0:
            raise ConfigError("atmosphere.wind_20ft_mps needs kind constant or dryden (calm has no mean wind)")
        if not 1.0 <= self.update_hz <= 10000.0:
            raise ConfigError(f"atmosphere.update_hz must be in [1, 10000] [Hz], got {self.update_hz!r}")
        if self.seed is not None and (isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0):
            raise ConfigError(f"atmosphere.seed must be an integer >= 0 or null, got {self.seed!r}")
        if self.grid_file is not None and (not isinstance(self.grid_file, str) or not self.grid_file):
            raise ConfigError(f"atmosphere.grid_file must be a path to an .npz or null, got {self.grid_file!r}")
        object.__setattr__(self, "shear", ShearConfig.parse(self.shear))
        object.__setattr__(self, "gusts", parse_gusts(self.gusts))

    @staticmethod
    def parse(value: Any) -> AtmosphereConfig | None:
        """null (off), a kind name, or a mapping."""
        if value is None or isinstance(value, AtmosphereConfig):
            return value
        if isinstance(value, str):
            return AtmosphereConfig(kind=value)
        return from_dict(AtmosphereConfig, value, "atmosphere")

    def to_data(self) -> dict[str, Any]:
        """Plain data that :meth:`parse` turns back into an equal config."""
        return {
            **{f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in ("shear", "gusts")},
            "shear": dataclasses.asdict(self.shear),
            "gusts": [dataclasses.asdict(g) for g in self.gusts],
        }

    def to_core(self, seed: int, base_dir: str | Path | None = None) -> Any:
        """The plant's atmosphere constants; ``seed`` is used when the config gives none."""
        a = _core.dynamics.AtmosphereParams()
        a.wind_20ft = 0.0 if self.kind == "calm" else self.wind_20ft_mps
        a.direction = math.radians(self.direction_deg)
        a.turbulence = self.kind == "dryden"
        a.shear = getattr(_core.dynamics.WindShear, _SHEAR_CORE[self.shear.kind])
        a.roughness_z0 = self.shear.z0_m
        a.shear_exponent = self.shear.exponent
        a.min_airspeed = self.min_airspeed_mps
        a.update_period = 1.0 / self.update_hz
        a.seed = (self.seed if self.seed is not None else seed) % 2**64
        a.gusts = [g.to_core() for g in self.gusts]
        if self.grid_file is not None:
            path = Path(self.grid_file)
            if not path.is_absolute() and base_dir is not None:
                path = Path(base_dir) / path
            g = load_wind_grid(path)
            a.set_grid(g.x, g.y, g.z, g.wind)
        err = _core.dynamics.validate_atmosphere(a)
        if err:
            raise ConfigError(err)
        return a


def apply_atmosphere(quad: Any, config: AtmosphereConfig | None, seed: int, base_dir: str | Path | None = None) -> None:
    """Makes ``quad`` (a Quadrotor or QuadrotorBatch) fly in ``config``'s air; None: leaves it as it is."""
    if config is not None:
        quad.set_atmosphere(config.to_core(seed, base_dir))

"""Ground and ceiling effect on rotor thrust: the scenario's ``ground_effect:`` (docs/guides/atmosphere.md).

Each rotor's thrust at hub height z above the floor and distance z_c below the ceiling is multiplied by

    T_IGE/T_OGE = 1 / (1 - (R/4z)^2 - R^2 z/(d^2 + 4z^2)^1.5 - (R^2/2) z/(2d^2 + 4z^2)^1.5 - 2 R^2 z K_b/(b^2 + 4z^2)^1.5)
    T_ICE/T_OCE = 1 / (1 - (1/K1) (R/(z_c + K2))^2)

the first Cheeseman & Bennett's single rotor (1955) with the multirotor terms of Sanchez-Cuevas, Heredia & Ollero
(2017, Int. J. Aerospace Eng. 1823056: d between adjacent rotors, b from rotor to body centre, K_b the body's
coefficient), the second their ceiling-effect fit (ICUAS 2017). Heights are clamped below at ``min_height_m``.
The plant evaluates the gains in C++ (``cpp/dynamics/ground_effect.h``) once per derivative; the floor and ceiling
heights come from the world (:mod:`cufund.worlds.surfaces`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund import _core
from cufund.core.config import ConfigError, check_real_fields, from_dict

from .params import QuadrotorParams

__all__ = ["GroundEffectConfig"]


@dataclass(frozen=True)
class GroundEffectConfig:
    """Ground and ceiling effect constants; ``ground_effect: true`` takes the defaults."""

    rotor_radius_m: float | None = None
    """Propeller radius R [m]; null: 0.385 arm lengths (CU-Astro's 3-inch propellers on its 99 mm arms: 38.1 mm);
    give it for other vehicles."""
    k_body: float = 2.0
    """K_b, the body term's coefficient (Sanchez-Cuevas et al. fit 2 for their quadrotor); 0 drops the term."""
    ceiling_k1: float = 6.924
    """K1 of the ceiling fit (.inf: no ceiling effect)."""
    ceiling_k2_m: float = 0.0
    """K2 of the ceiling fit [m]."""
    rotor_plane_height_m: float = 0.05
    """Height of the rotor hubs above the body origin along body z [m]: the origin rests on the ground, the
    propellers stand above it on the landing gear (CU-Astro, 95 mm tall: about 5 cm; give it for other vehicles)."""
    min_height_m: float | None = None
    """Heights below this count as this [m]; null: one rotor radius (where the fits' data end)."""
    surface_labels: tuple[str, ...] | None = ("floor", "ground", "ceiling", "terrain", "roof")
    """The world objects that count as floor or ceiling, by label (the models hold for a plane, not a thin bar);
    null: every object."""
    update_hz: float = 20.0
    """How often the floor and ceiling under and over the vehicle are looked up in the world [Hz]."""

    def __post_init__(self) -> None:
        for name in ("rotor_radius_m", "min_height_m"):
            v = getattr(self, name)
            if v is not None:
                check_real_fields(self, "ground_effect", positive=True, unit=" [m]", names=(name,))
        check_real_fields(self, "ground_effect", names=("k_body", "ceiling_k2_m", "rotor_plane_height_m"))
        check_real_fields(self, "ground_effect", positive=True, names=("update_hz",))
        if self.surface_labels is not None:
            labels = self.surface_labels
            if isinstance(labels, str) or not all(isinstance(x, str) for x in labels):
                raise ConfigError(f"ground_effect.surface_labels must be a list of labels or null, got {labels!r}")
            object.__setattr__(self, "surface_labels", tuple(labels))
        if (
            isinstance(self.ceiling_k1, bool)
            or not isinstance(self.ceiling_k1, (int, float))
            or not self.ceiling_k1 > 0
        ):
            raise ConfigError(
                f"ground_effect.ceiling_k1 must be a number > 0 (.inf: no ceiling), got {self.ceiling_k1!r}"
            )

    @staticmethod
    def parse(value: Any) -> GroundEffectConfig | None:
        """``false``/null: off; ``true``: the defaults; a mapping: overrides."""
        if value is None or value is False:
            return None
        if value is True:
            return GroundEffectConfig()
        if isinstance(value, GroundEffectConfig):
            return value
        if not isinstance(value, dict):
            raise ConfigError(f"ground_effect must be true, false or a mapping, got {value!r}")
        return from_dict(GroundEffectConfig, value, "ground_effect")

    def to_data(self) -> Any:
        return True if self == GroundEffectConfig() else {k: getattr(self, k) for k in self.__dataclass_fields__}

    def radius(self, params: QuadrotorParams) -> float:
        return self.rotor_radius_m if self.rotor_radius_m is not None else 0.385 * params.arm_length

    def to_core(self, params: QuadrotorParams) -> Any:
        """The plant's constants for ``params`` (d: the closest rotor pair, b: the arm length)."""
        r = params.rotor_positions()
        g = _core.dynamics.GroundEffectParams()
        g.enabled = True
        g.rotor_radius = self.radius(params)
        g.rotor_spacing = min(float(np.linalg.norm(r[i] - r[j])) for i, j in itertools.combinations(range(4), 2))
        g.body_distance = params.arm_length
        g.k_body = self.k_body
        g.ceiling_k1 = float(self.ceiling_k1)
        g.ceiling_k2 = self.ceiling_k2_m
        g.rotor_plane_height = self.rotor_plane_height_m
        g.min_height = self.min_height_m if self.min_height_m is not None else g.rotor_radius
        err = _core.dynamics.validate_ground_effect(g)
        if err:
            raise ConfigError(err)
        return g

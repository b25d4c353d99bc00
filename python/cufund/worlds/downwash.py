"""Rotor downwash of one vehicle on another below it: the scenario's ``downwash:`` (docs/guides/fleets.md).

The air a hovering multirotor pushes down is modelled as the self-similar turbulent round jet of classical theory
(Pope, *Turbulent Flows*, 2000, §5.1; constants of Hussein, Capp & George, J. Fluid Mech. 258, 1994), issuing
along the upper vehicle's thrust axis (-z_B) from its body origin; Bauersfeld, Muller, Ziegler, Coletti &
Scaramuzza ("Robotics meets Fluid Dynamics: a characterization of the induced airflow below a quadrotor as a
turbulent jet", IEEE RA-L 2025, arXiv:2403.13321) measured the combined flow of a quadrotor's four propellers to
follow such a jet from about 2.5 vehicle sizes below it. With the jet's (kinematic) momentum flux ``M = T / rho``
(T: the upper vehicle's total thrust [N]) and ``s`` the distance below the source along the axis, ``r`` from it:

    U_c(s)   = min(U_J, B sqrt(4 M / pi) / s)          centreline speed, B = 5.8
    b(s)     = max(d_J / 2, S s)                        half-width (where U = U_c / 2), S = 0.094
    U(s, r)  = U_c(s) exp(-ln 2 (r / b)^2)              for s > 0 and r <= 3 b; 0 elsewhere

U_J = 2 sqrt(T / (2 rho A)) is the fully developed slipstream speed of momentum theory (A: the four rotor discs)
and d_J the diameter of a round jet of that speed and momentum flux: near the vehicle the speed is capped at U_J
rather than growing without bound. Beyond three half-widths (where the profile is 0.2 % of the centreline) the jet
is cut off, so a vehicle laterally clear of another feels exactly nothing.

The vehicle below loses thrust to the descending air as a rotor does in axial inflow; the model takes it as the
force ``F = 1/2 rho C A_r u |u|`` on each of its rotors (A_r one rotor disc, u the jet's velocity at the rotor's
centre, C ``thrust_loss_coefficient``), summed and applied to the plant as an external force (world frame) by the
fleet (:mod:`cufund.simulator.fleet`). Jain, Fortmuller, Byun, Mäkiharju & Mueller ("Modeling of aerodynamic
disturbances for proximity flight of multirotors", ICUAS 2019) build the same chain (a propeller velocity field,
then the thrust change of a propeller under oncoming flow) and found it to match flight data for vertical
separations above about seven vehicle sizes; closer, the model is an estimate. No torque is applied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, check_real_fields, from_dict

__all__ = ["DownwashConfig", "downwash_force", "jet_reach", "jet_speed", "jet_velocity"]

JET_B = 5.8
"""Centreline decay constant B of the round jet (Hussein et al. 1994; Pope 2000, Table 5.1)."""
JET_S = 0.094
"""Spreading rate S of the round jet: half-width per distance (Hussein et al. 1994; Pope 2000)."""
CUTOFF_HALF_WIDTHS = 3.0
"""The jet is zero beyond this many half-widths from its axis."""


@dataclass(frozen=True)
class DownwashConfig:
    """The downwash model's constants; ``downwash: true`` takes the defaults (off when absent)."""

    air_density: float = 1.225
    """rho [kg/m^3] (ISA sea level)."""
    rotor_radius_m: float | None = None
    """Propeller radius [m]; null: 0.385 arm lengths, as the ground effect's default (CU-Astro's 3-inch props)."""
    thrust_loss_coefficient: float = 1.0
    """C in F = 1/2 rho C A_r u |u| per rotor (1: the jet's dynamic pressure over the rotor disc)."""
    max_range_m: float = 30.0
    """Vehicles farther apart than this are not checked (the jet has decayed to a few cm/s) [m]."""

    def __post_init__(self) -> None:
        check_real_fields(
            self, "downwash", positive=True, names=("air_density", "thrust_loss_coefficient", "max_range_m")
        )
        if self.rotor_radius_m is not None:
            check_real_fields(self, "downwash", positive=True, unit=" [m]", names=("rotor_radius_m",))

    @staticmethod
    def parse(value: Any) -> DownwashConfig | None:
        """``false``/null: off; ``true``: the defaults; a mapping: overrides."""
        if value is None or value is False:
            return None
        if value is True:
            return DownwashConfig()
        if isinstance(value, DownwashConfig):
            return value
        if not isinstance(value, dict):
            raise ConfigError(f"downwash must be true, false or a mapping, got {value!r}")
        return from_dict(DownwashConfig, value, "downwash")

    def to_data(self) -> Any:
        return True if self == DownwashConfig() else {k: getattr(self, k) for k in self.__dataclass_fields__}

    def radius(self, arm_length: float) -> float:
        """The propeller radius [m] of a vehicle with arms of ``arm_length`` [m]."""
        return self.rotor_radius_m if self.rotor_radius_m is not None else 0.385 * float(arm_length)


def jet_speed(thrust_N: float, s: Any, r: Any, rotor_radius_m: float, air_density: float = 1.225) -> np.ndarray:
    """The jet's speed [m/s] at distances ``s`` below the source along its axis and ``r`` from the axis [m]
    (arrays of one shape) of a vehicle of total thrust ``thrust_N`` and four rotors of ``rotor_radius_m``."""
    s, r = np.asarray(s, dtype=float), np.asarray(r, dtype=float)
    if not thrust_N > 0:
        return np.zeros(np.broadcast(s, r).shape)
    M = thrust_N / air_density  # kinematic momentum flux [m^4/s^2]
    A = 4.0 * math.pi * rotor_radius_m**2
    u_j = 2.0 * math.sqrt(thrust_N / (2.0 * air_density * A))
    d_j = math.sqrt(4.0 * M / (math.pi * u_j * u_j))  # (pi/4) d^2 u_j^2 = M
    with np.errstate(divide="ignore", invalid="ignore"):
        u_c = np.minimum(u_j, JET_B * math.sqrt(4.0 * M / math.pi) / s)
    b = np.maximum(0.5 * d_j, JET_S * s)
    eta = r / b
    out = u_c * np.exp(-math.log(2.0) * eta * eta)
    return np.where((s > 0) & (eta <= CUTOFF_HALF_WIDTHS), out, 0.0)


def jet_reach(s: Any, rotor_radius_m: Any) -> np.ndarray:
    """How far from its axis the jet of a vehicle with propellers of ``rotor_radius_m`` is non-zero at ``s`` below
    it [m] (whatever its thrust: d_J = 2 sqrt(2) R follows from momentum theory): ``CUTOFF_HALF_WIDTHS b(s)``."""
    s = np.asarray(s, dtype=float)
    radius = np.asarray(rotor_radius_m, dtype=float)
    return CUTOFF_HALF_WIDTHS * np.maximum(math.sqrt(2.0) * radius, JET_S * np.maximum(s, 0.0))


def jet_velocity(
    thrust_N: float, p_W: Any, R_WB: Any, points_W: Any, rotor_radius_m: float, air_density: float = 1.225
) -> np.ndarray:
    """The jet's velocity (K, 3) [m/s, world] at ``points_W`` (K, 3) below a vehicle at ``p_W`` with attitude
    ``R_WB`` and total thrust ``thrust_N``: along its -z_B."""
    R = np.asarray(R_WB, dtype=float)
    axis = -R[:, 2]  # -z_B in the world
    d = np.asarray(points_W, dtype=float) - np.asarray(p_W, dtype=float)
    s = d @ axis
    r = np.linalg.norm(d - s[:, None] * axis, axis=1)
    return jet_speed(thrust_N, s, r, rotor_radius_m, air_density)[:, None] * axis


def downwash_force(
    config: DownwashConfig,
    sources: list[tuple[float, np.ndarray, np.ndarray, float]],
    rotors_W: np.ndarray,
    rotor_radius_m: float,
) -> np.ndarray:
    """The force (3,) [N, world] on a vehicle whose rotor centres are ``rotors_W`` (4, 3) and propellers of
    ``rotor_radius_m``, from the jets of ``sources``: each (total thrust [N], p_W, R_WB, its propeller radius)."""
    u = np.zeros((len(rotors_W), 3))
    for thrust, p, R, radius in sources:
        u += jet_velocity(thrust, p, R, rotors_W, radius, config.air_density)
    speed = np.linalg.norm(u, axis=1)
    area = math.pi * rotor_radius_m**2
    return 0.5 * config.air_density * config.thrust_loss_coefficient * area * np.sum(u * speed[:, None], axis=0)

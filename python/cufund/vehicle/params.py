"""Quadrotor physical parameters: a typed, frozen, validated record (paper §2.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cufund import _core
from cufund.core.config import ConfigError, from_dict, load_yaml, real_number, to_dict, vector3

_LAYOUTS = {"x": _core.dynamics.RotorLayout.X, "+": _core.dynamics.RotorLayout.PLUS}


def _matrix3(name: str, value: Any) -> tuple[tuple[float, float, float], ...]:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{name} must be a 3x3 matrix or 3 diagonal entries of real numbers: {e}") from None
    if a.shape == (3,):
        a = np.diag(a)
    if a.shape != (3, 3):
        raise ConfigError(f"{name} must be a 3x3 matrix or 3 diagonal entries, got shape {a.shape}")
    r0, r1, r2 = (tuple(float(x) for x in row) for row in a)
    return ((r0[0], r0[1], r0[2]), (r1[0], r1[1], r1[2]), (r2[0], r2[1], r2[2]))


@dataclass(frozen=True)
class QuadrotorParams:
    """Physical parameters of a quadrotor. SI units; body frame FLU, world ENU.

    Rotor ``i`` makes thrust ``f_i = k_f * omega_i**2`` along body +z and a reaction torque
    ``-s_i * c_m * f_i`` about body z (``s_i = +1`` for a rotor spinning counter-clockwise seen from
    above). Rotor speeds follow their commands through a first-order lag ``tau_m`` and saturate at
    ``[rotor_speed_min, rotor_speed_max]``. Invalid values raise :class:`ValueError` naming the field.
    """

    mass: float
    """Total mass [kg], > 0."""
    inertia: tuple[tuple[float, float, float], ...]
    """Inertia about the centre of mass in body FLU [kg m^2]; symmetric positive definite. YAML may give the
    3 diagonal entries."""
    arm_length: float
    """Distance d from the centre of mass to each rotor centre [m]."""
    k_f: float
    """Thrust coefficient [N/(rad/s)^2]."""
    c_m: float
    """Reaction-torque-to-thrust ratio, the paper's c_M [m] (= k_m / k_f)."""
    tau_m: float
    """Motor time constant [s]."""
    rotor_speed_max: float
    """Highest rotor speed [rad/s]."""
    rotor_speed_min: float = 0.0
    """Lowest rotor speed [rad/s]."""
    layout: str = "x"
    """``"x"`` (PX4 quad-x numbering: 1 front-right, 2 rear-left, 3 front-left, 4 rear-right; 1 and 2
    counter-clockwise) or ``"+"`` (1 front, 2 right, 3 back, 4 left; 1 and 3 clockwise; paper eq. 1)."""
    rotor_drag_xy: float = 0.0
    """Rotor drag in the rotor plane, ``H_i = -omega_i * k * v_air_i`` [N/((rad/s)(m/s))] = [kg/rad]."""
    rotor_drag_z: float = 0.0
    """Rotor drag (induced inflow) along the rotor axis [kg/rad]."""
    body_drag: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Quadratic body drag ``D = -|v_air| * diag(body_drag) * v_air`` in body FLU [N/(m/s)^2]."""
    gravity: float = 9.80665
    """Gravitational acceleration [m/s^2]."""
    ground_plane: bool = True
    """A rigid ground at z = 0 that the vehicle rests on and takes off from."""
    ground_attitude: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """The attitude [w, x, y, z] the vehicle takes resting on the ground, its yaw kept: level, or a tilted take-off
    pad's (at most 30 deg; the scenario's ``realism.vehicle.pad_tilt_max_deg`` draws one for the simulated plant)."""
    max_integration_step: float = 1e-3
    """Largest RK4 sub-step [s]; a step of dt is split into ceil(dt / this) equal sub-steps (1 kHz default)."""
    name: str = field(default="custom", compare=False)
    """A label for logs and plots."""

    def __post_init__(self) -> None:
        for f in (
            "mass",
            "arm_length",
            "k_f",
            "c_m",
            "tau_m",
            "rotor_speed_max",
            "rotor_speed_min",
            "rotor_drag_xy",
            "rotor_drag_z",
            "gravity",
            "max_integration_step",
        ):
            object.__setattr__(self, f, real_number(f, getattr(self, f)))
        object.__setattr__(self, "inertia", _matrix3("inertia", self.inertia))
        object.__setattr__(self, "body_drag", vector3("body_drag", self.body_drag))
        try:
            g = np.asarray(self.ground_attitude, dtype=float)
        except (TypeError, ValueError):
            g = np.full(1, np.nan)
        if g.shape != (4,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"ground_attitude must be 4 finite numbers [w, x, y, z], got {self.ground_attitude!r}")
        object.__setattr__(self, "ground_attitude", (float(g[0]), float(g[1]), float(g[2]), float(g[3])))
        if not isinstance(self.layout, str) or self.layout not in _LAYOUTS:
            raise ConfigError(f"layout must be one of 'x', '+', got {self.layout!r}")
        if not isinstance(self.ground_plane, bool):
            raise ConfigError(f"ground_plane must be true or false, got {self.ground_plane!r}")
        err = _core.dynamics.validate_params(self.to_core())
        if err:
            raise ConfigError(err)

    def to_core(self) -> Any:
        """The C++ parameter record (internal)."""
        c = _core.dynamics.QuadrotorParams()
        c.mass = self.mass
        c.inertia = np.asarray(self.inertia, dtype=float)
        c.arm_length = self.arm_length
        c.layout = _LAYOUTS[self.layout]
        c.k_f = self.k_f
        c.c_m = self.c_m
        c.tau_m = self.tau_m
        c.rotor_speed_min = self.rotor_speed_min
        c.rotor_speed_max = self.rotor_speed_max
        c.rotor_drag_xy = self.rotor_drag_xy
        c.rotor_drag_z = self.rotor_drag_z
        c.body_drag = np.asarray(self.body_drag, dtype=float)
        c.gravity = self.gravity
        c.ground_plane = self.ground_plane
        c.ground_attitude = np.asarray(self.ground_attitude, dtype=float)
        c.max_integration_step = self.max_integration_step
        return c

    @property
    def hover_rotor_speed(self) -> float:
        """Rotor speed at which four rotors carry the weight [rad/s]."""
        return math.sqrt(self.mass * self.gravity / (4.0 * self.k_f))

    @property
    def max_thrust(self) -> float:
        """Collective thrust of four rotors at rotor_speed_max [N] (the thrust-to-weight ratio is this over m g)."""
        return 4.0 * self.k_f * self.rotor_speed_max**2

    @property
    def inertia_matrix(self) -> np.ndarray:
        """J as a (3, 3) array [kg m^2]."""
        return np.array(self.inertia)

    def allocation_matrix(self) -> np.ndarray:
        """A (4, 4) of the paper's eq. (1) in FLU: rotor thrusts [N] -> [f, M_x, M_y, M_z]."""
        return _core.dynamics.allocation_matrix(self.to_core())

    def allocation_matrix_inverse(self) -> np.ndarray:
        """A^-1 (4, 4): [f, M_x, M_y, M_z] -> rotor thrusts [N], without saturation."""
        return _core.dynamics.allocation_matrix_inverse(self.to_core())

    def rotor_positions(self) -> np.ndarray:
        """Rotor centres in body FLU [m], shape (4, 3), in the layout's numbering."""
        return _core.dynamics.rotor_positions(self.to_core())

    def rotor_spins(self) -> np.ndarray:
        """+1 for rotors spinning counter-clockwise seen from above, -1 clockwise, shape (4,)."""
        return _core.dynamics.rotor_spins(self.to_core())

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> QuadrotorParams:
        """From a mapping with this class's field names; unknown keys raise."""
        return from_dict(cls, data, "QuadrotorParams")

    @classmethod
    def from_yaml(cls, path: str | Path) -> QuadrotorParams:
        """From a YAML file whose top level holds this class's fields."""
        return cls.from_dict(load_yaml(path))

    def to_dict(self) -> dict[str, Any]:
        """Plain data that :meth:`from_dict` turns back into an equal object."""
        return to_dict(self)

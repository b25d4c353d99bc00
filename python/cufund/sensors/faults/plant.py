"""Faults of the vehicle itself: a motor that stops or loses efficiency, and a propeller out of balance.

They act on the simulated plant (never on what flight software is told), through its held inputs, at every physics
node from their start time (:class:`PlantFaults`, a harness component running at the physics rate):

- ``motor_failure``: rotor ``motor`` (0-3, the vehicle's numbering: PX4's quad-x order for an ``x`` layout) makes
  no thrust and no drag torque from ``t_start`` (``Quadrotor.set_rotor_efficiency``: efficiency 0), and spins down:
  its speed decays as ``omega(t_start) exp(-(t - t_start) / tau_m)`` with the plant's motor time constant, whatever
  the controller commands (an ESC that lost its motor; the rotor's drag and the IMU's vibration follow the speed).
- ``motor_efficiency``: rotor ``motor`` makes ``efficiency`` (in (0, 1]) of its thrust and drag torque from
  ``t_start``, reached linearly over ``ramp_s`` (0: a step): a damaged propeller, a weak motor or ESC.
- ``prop_imbalance``: rotor ``motor``'s propeller carries an imbalance ``imbalance_kg_m`` = m r [kg m] (a mass m at
  radius r off the axis). It adds the centrifugal force m r omega^2 in the rotor plane, turning with the rotor's
  angle phi (integrated from the true rotor speed, the trapezoid rule, from a seeded random angle at ``t_start``;
  counter-clockwise for a rotor spinning so), applied at the rotor hub: a force in the body's xy plane and the
  torque r_hub x F. The plant integrates it like any external force (``force_ext_W``/``torque_ext_B``, held over a
  physics step: a zero-order hold sampled at the physics nodes; the body's velocity sees sinc(pi f / f_s) of the
  line, 84 % for CU-Astro's 317 Hz hover rotor rate at 1 kHz, and a rotor rate above half the physics rate aliases:
  raise ``rates.physics_hz`` to resolve it better), so it reaches the IMU only through the body's motion, as on a
  real vehicle (the IMU reads each step's acceleration, the force at its node in full).

Several faults on one rotor multiply their efficiencies. Their contributions are added to the plant's external
force and torque (what else sets them, e.g. a gust model, is kept).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from cufund.core.components import Component
from cufund.core.config import ConfigError
from cufund.geometry import quat_to_matrix

from .common import check_real, check_time

_log = logging.getLogger("cufund.faults")

__all__ = ["MotorEfficiency", "MotorFailure", "PlantFault", "PlantFaults", "PropImbalance", "plant_faults"]


def _motor(where: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 3:
        raise ConfigError(f"{where} must be a rotor index 0-3 (the vehicle's numbering), got {value!r}")
    return value


class PlantFault:
    """A fault of the simulated vehicle (a mixin of the frozen params dataclasses)."""

    kind: ClassVar[str]
    sensor_type: ClassVar[None] = None
    """None: no sensor; the plant's."""
    t_start: float
    motor: int

    def efficiency_at(self, t: float) -> float:
        """The rotor's efficiency factor at time t (1: no effect)."""
        return 1.0


@dataclass(frozen=True)
class MotorFailure(PlantFault):
    """Rotor ``motor`` stops at ``t_start``: no thrust, no drag torque, its speed decays with the motor lag."""

    t_start: float
    """When the motor fails (simulated time) [s]."""
    motor: int = 0
    """The rotor, 0-3 (the vehicle's numbering)."""

    kind = "motor_failure"

    def __post_init__(self) -> None:
        object.__setattr__(self, "t_start", check_time(f"faults.{self.kind}.t_start", self.t_start))
        _motor(f"faults.{self.kind}.motor", self.motor)

    def efficiency_at(self, t: float) -> float:
        return 0.0 if t >= self.t_start else 1.0


@dataclass(frozen=True)
class MotorEfficiency(PlantFault):
    """Rotor ``motor`` loses efficiency from ``t_start``: thrust and drag torque times ``efficiency``, reached
    linearly over ``ramp_s``."""

    t_start: float
    """When the loss starts (simulated time) [s]."""
    motor: int = 0
    """The rotor, 0-3 (the vehicle's numbering)."""
    efficiency: float = 0.8
    """Thrust and drag-torque factor once the loss is complete, in (0, 1] (``motor_failure`` for 0)."""
    ramp_s: float = 0.0
    """Time over which the efficiency falls linearly from 1 [s] (0: a step)."""

    kind = "motor_efficiency"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        _motor(f"{w}.motor", self.motor)
        object.__setattr__(self, "efficiency", check_real(f"{w}.efficiency", self.efficiency, 0.0, 1.0, "", True))
        object.__setattr__(self, "ramp_s", check_time(f"{w}.ramp_s", self.ramp_s))

    def efficiency_at(self, t: float) -> float:
        if t < self.t_start:
            return 1.0
        if self.ramp_s == 0 or t >= self.t_start + self.ramp_s:
            return self.efficiency
        return 1.0 + (self.efficiency - 1.0) * (t - self.t_start) / self.ramp_s


@dataclass(frozen=True)
class PropImbalance(PlantFault):
    """Rotor ``motor``'s propeller is out of balance by ``imbalance_kg_m`` (mass x radius) from ``t_start``."""

    t_start: float
    """When the imbalance appears (a chipped blade) (simulated time) [s]."""
    motor: int = 0
    """The rotor, 0-3 (the vehicle's numbering)."""
    imbalance_kg_m: float = 1e-6
    """Mass times its radius off the rotor axis [kg m], in (0, 1e-4] (1e-6: 0.1 g at 1 cm, a chipped small
    propeller: 4 N at 2000 rad/s; a propeller balanced to ISO 1940 G6.3 is near 1e-8)."""

    kind = "prop_imbalance"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        _motor(f"{w}.motor", self.motor)
        object.__setattr__(
            self, "imbalance_kg_m", check_real(f"{w}.imbalance_kg_m", self.imbalance_kg_m, 0.0, 1e-4, " [kg m]", True)
        )


class PlantFaults(Component):
    """Applies the plant's faults to ``plant`` (a :class:`cufund.vehicle.Quadrotor`) at every physics node: a
    harness part (it runs with the simulated world, reads no topic and publishes none)."""

    name = "plant_faults"
    inputs = ()
    outputs = ()

    def __init__(self, faults: list[PlantFault], plant: Any, rate_hz: float, seeds: list[int]) -> None:
        self.faults, self.plant, self.rate_hz, self.seeds = list(faults), plant, float(rate_hz), list(seeds)
        self._r_B: list[list[float]] = np.asarray(plant.params.rotor_positions(), dtype=float).tolist()
        self._spin: list[float] = np.asarray(plant.params.rotor_spins(), dtype=float).tolist()
        self._tau = float(plant.params.tau_m)
        self._t_first = min(f.t_start for f in self.faults)
        # From _t_settled on every fault has started and every efficiency is constant: eta needs no more work.
        self._t_settled = max(
            f.t_start + f.ramp_s if isinstance(f, MotorEfficiency) else f.t_start for f in self.faults
        )
        self._eta_faults = [f for f in self.faults if not isinstance(f, PropImbalance)]
        self._failures = [f for f in self.faults if isinstance(f, MotorFailure)]
        self._imbalances = [(i, f) for i, f in enumerate(self.faults) if isinstance(f, PropImbalance)]
        self._touched_eta = False
        self._force_W = np.zeros(3)
        self._torque_B = np.zeros(3)
        self.reset()

    def reset(self) -> None:
        """Undoes what the last run left on the plant; the rotor angles drawn again from the seeds."""
        if self._touched_eta:
            self.plant.set_rotor_efficiency(np.ones(4))
            self._touched_eta = False
        self.plant.force_ext_W[:] -= self._force_W
        self.plant.torque_ext_B[:] -= self._torque_B
        self._force_W, self._torque_B = np.zeros(3), np.zeros(3)
        self._eta = np.ones(4)
        self._phase: dict[int, float] = {}  # fault index -> rotor angle [rad], from its start
        self._omega_prev: dict[int, float] = {}
        self._t_prev: float | None = None
        self._eta_settled = False
        self._stopped: dict[int, tuple[float, float]] = {}  # rotor -> (t_start, speed then)
        self.started: set[int] = set()
        """Indices of the faults that have begun acting in this run."""

    def step(self, t: float, bus: Any) -> None:
        if t < self._t_first:  # before the first fault: nothing to do
            return
        plant = self.plant
        if not self._eta_settled:
            eta = np.ones(4)
            for i, f in enumerate(self.faults):
                if t >= f.t_start:
                    if not isinstance(f, PropImbalance):  # its efficiency is 1
                        eta[f.motor] *= f.efficiency_at(t)
                    if i not in self.started:
                        self.started.add(i)
                        _log.info("fault %s acts from t = %.6f s: %r", f.kind, t, f)
            if not np.array_equal(eta, self._eta):
                plant.set_rotor_efficiency(eta)
                self._eta, self._touched_eta = eta, True
            self._eta_settled = t >= self._t_settled
        omega = plant.state.rotor_speeds
        for f in self._failures:
            if t >= f.t_start:
                t0, w0 = self._stopped.setdefault(f.motor, (t, float(omega[f.motor])))
                omega[f.motor] = w0 * math.exp(-(t - t0) / self._tau)
        if not self._imbalances:
            return
        dt = 0.0 if self._t_prev is None else t - self._t_prev
        self._t_prev = t
        # In Python floats (a few numbers: numpy's per-call cost dominated), in numpy's order of operations.
        fx = fy = tx = ty = tz = 0.0
        for i, f in self._imbalances:
            if t < f.t_start:
                continue
            w = float(omega[f.motor])
            if i not in self._phase:  # its first node: a random angle from the fault's own seeded stream
                self._phase[i] = float(np.random.default_rng(self.seeds[i]).uniform(0.0, 2.0 * math.pi))
            else:
                self._phase[i] += 0.5 * (self._omega_prev[i] + w) * dt * self._spin[f.motor]
            self._omega_prev[i] = w
            phi = self._phase[i]
            a = f.imbalance_kg_m * w * w
            Fx, Fy = a * math.cos(phi), a * math.sin(phi)
            rx, ry, rz = self._r_B[f.motor]
            fx, fy = fx + Fx, fy + Fy
            tx, ty, tz = tx + (ry * 0.0 - rz * Fy), ty + (rz * Fx - rx * 0.0), tz + (rx * Fy - ry * Fx)
        if fx or fy or self._force_W.any():
            force_B, torque_B = np.array([fx, fy, 0.0]), np.array([tx, ty, tz])
            R_WB = quat_to_matrix(np.asarray(plant.state.q))
            force_W = R_WB @ force_B
            plant.force_ext_W[:] += force_W - self._force_W
            plant.torque_ext_B[:] += torque_B - self._torque_B
            self._force_W, self._torque_B = force_W, torque_B


def plant_faults(
    faults: tuple[Any, ...], plant: Any, physics_rate_hz: float, seed_for: Callable[[str], int]
) -> list[Component]:
    """The component applying the plant's faults among ``faults`` to ``plant`` (none without such faults)."""
    mine = [(i, f) for i, f in enumerate(faults) if isinstance(f, PlantFault)]
    if not mine:
        return []
    if plant is None:
        raise ConfigError(f"faults.{mine[0][1].kind} acts on the vehicle; this run simulates none")
    return [
        PlantFaults([f for _, f in mine], plant, physics_rate_hz, [seed_for(f"faults[{i}].{f.kind}") for i, f in mine])
    ]

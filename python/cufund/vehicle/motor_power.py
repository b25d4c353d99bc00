"""Electrical power of the rotors, from the vehicle's own constants, and the rotor speed the supply voltage allows.

**Power.** Rotor ``i`` turning at ``omega_i`` [rad/s] makes the drag torque ``k_m omega_i^2`` with
``k_m = c_m k_f`` (the presets' reaction-torque and thrust coefficients, :class:`~cufund.vehicle.QuadrotorParams`),
so its shaft takes ``P_i = k_m omega_i^3`` [W]. Motor and ESC turn electrical into shaft power with the efficiency
``eta`` (:attr:`MotorPowerParams.efficiency`); the avionics draw a constant base load on top::

    P_el = sum_i eta_rotor_i k_m omega_i^3 / eta + P_avionics

(``eta_rotor_i``: the plant's per-rotor efficiency, 1 for a healthy rotor, 0 for a stopped one.) The battery
supplies ``P_el`` at its terminal voltage: ``I = P_el / V`` (:meth:`cufund.vehicle.battery.Battery.current_for_power`).

**Speed limit.** A brushless motor's speed is bounded by its back-EMF: ``omega <= Kv V`` (no load), and under load
``k_e omega <= V - I R_winding``. With a constant ``Kv`` and the winding drop taken proportional to the supply, the
largest speed scales with the voltage::

    omega_max(V) = omega_max_nominal * V / V_nominal

where ``omega_max_nominal`` is the preset's ``rotor_speed_max``, read as the speed at the full pack's open-circuit
voltage ``V_nominal`` (:attr:`cufund.vehicle.battery.BatteryParams.full_voltage`); the limit never exceeds it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, check_real_fields, from_dict, to_dict

from .params import QuadrotorParams

__all__ = ["MotorPower", "MotorPowerParams"]


@dataclass(frozen=True)
class MotorPowerParams:
    """How much electrical power the rotors and avionics draw."""

    efficiency: float = 0.75
    """Motor and ESC efficiency, shaft power / electrical power, in (0, 1]. Default 0.75: a small brushless
    outrunner near its hover load is 75 to 85 % efficient and its ESC ~95 % (an estimate; a test stand's
    thrust-per-watt figures give yours)."""
    avionics_w: float = 5.0
    """Constant base load of everything but the motors [W], >= 0. Default 5 W: a flight controller, receiver, ESC
    standby and a small companion computer. A LiDAR vehicle draws more (a Livox Mid-360: 6.5 W typical by its
    datasheet, plus its computer)."""

    def __post_init__(self) -> None:
        check_real_fields(self, "battery", positive=True, names=("efficiency",))
        check_real_fields(self, "battery", unit=" [W]", names=("avionics_w",))
        if self.efficiency > 1.0:
            raise ConfigError(
                f"battery.efficiency must be in (0, 1] (shaft / electrical power), got {self.efficiency!r}"
            )
        if self.avionics_w > 1e5:
            raise ConfigError(f"battery.avionics_w must be at most 1e5 W, got {self.avionics_w!r}")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MotorPowerParams:
        return from_dict(cls, data, "battery")

    def to_dict(self) -> dict[str, Any]:
        return to_dict(self)


class MotorPower:
    """The power model of one vehicle (its :class:`QuadrotorParams`) with :class:`MotorPowerParams`."""

    def __init__(self, vehicle: QuadrotorParams, params: MotorPowerParams | None = None) -> None:
        if not isinstance(vehicle, QuadrotorParams):
            raise TypeError(f"vehicle must be a cufund.QuadrotorParams, got {type(vehicle).__name__}")
        self.vehicle = vehicle
        self.params = params if params is not None else MotorPowerParams()
        self.k_m = vehicle.c_m * vehicle.k_f
        """Drag-torque coefficient k_m = c_m k_f [N m/(rad/s)^2]."""

    def shaft_power_w(self, rotor_speeds: np.ndarray, rotor_efficiency: np.ndarray | None = None) -> float:
        """Mechanical power the rotors take, sum eta_rotor_i k_m |omega_i|^3 [W], for (4,) speeds [rad/s]."""
        w = np.asarray(rotor_speeds, dtype=float).tolist()  # four numbers: cheaper in Python than in numpy
        if rotor_efficiency is None:
            return self.k_m * sum(abs(x) ** 3 for x in w)
        eta = np.asarray(rotor_efficiency, dtype=float).tolist()
        return self.k_m * sum(e * abs(x) ** 3 for x, e in zip(w, eta, strict=True))

    def electrical_power_w(self, rotor_speeds: np.ndarray, rotor_efficiency: np.ndarray | None = None) -> float:
        """P_el = shaft power / efficiency + avionics [W]."""
        return self.shaft_power_w(rotor_speeds, rotor_efficiency) / self.params.efficiency + self.params.avionics_w

    def hover_power_w(self) -> float:
        """P_el in steady hover: four rotors at the hover speed sqrt(m g / (4 k_f)) [W]."""
        return self.electrical_power_w(np.full(4, self.vehicle.hover_rotor_speed))

    def max_rotor_speed(self, voltage_v: float, nominal_voltage_v: float) -> float:
        """omega_max(V) = rotor_speed_max * V / V_nominal, clamped between rotor_speed_min and rotor_speed_max [rad/s]."""
        if not nominal_voltage_v > 0.0:
            raise ValueError(f"nominal_voltage_v must be > 0 [V], got {nominal_voltage_v!r}")
        ratio = min(max(voltage_v / nominal_voltage_v, 0.0), 1.0)
        return max(self.vehicle.rotor_speed_max * ratio, self.vehicle.rotor_speed_min)

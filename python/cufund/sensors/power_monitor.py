"""The flight battery in a run: the plant side (the pack discharged by what the rotors draw, the rotor-speed limit
that falls as its voltage sags) and the power module that measures it (:class:`BatteryStatus` on ``/battery``).

A scenario turns it on with ``vehicle.battery`` (off when absent: nothing here runs, and a run is what it was)::

    vehicle:
      preset: cu_astro
      battery: {cells: 4, capacity_mah: 850, avionics_w: 12}

The keys are one flat mapping: the pack's (:class:`~cufund.vehicle.battery.BatteryParams`), the power draw's
(:class:`~cufund.vehicle.motor_power.MotorPowerParams`) and the power module's (:class:`PowerMonitorParams`).

At each of its ticks the :class:`PowerMonitor` (a simulated part, so it reads the true rotor speeds) advances the
pack exactly over the time since the last tick with the current it drew then, computes the electrical power of the
rotors now (:class:`~cufund.vehicle.motor_power.MotorPower`) and the current the pack gives for it, sets the plant's
rotor-speed limit from the terminal voltage (``Quadrotor.set_max_rotor_speed``), and publishes the power module's
reading: voltage and current with white noise from the scenario's seed, the state of charge and the charge drawn.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.components import Sensor
from cufund.core.config import ConfigError, check_at_most, check_real_fields, to_dict
from cufund.core.messages import BatteryStatus, Odometry, Topics
from cufund.vehicle.battery import Battery, BatteryParams
from cufund.vehicle.motor_power import MotorPower, MotorPowerParams
from cufund.vehicle.params import QuadrotorParams

__all__ = ["PowerMonitor", "PowerMonitorParams", "PowerSystem"]


@dataclass(frozen=True)
class PowerMonitorParams:
    """The power module (a current shunt and a voltage divider read by the flight controller, like a Holybro PM02D
    or an INA226) and how often the pack is advanced."""

    rate_hz: float = 20.0
    """How often the pack is advanced, the rotor-speed limit updated and the reading published [Hz]. Default 20 Hz:
    the pack's transients take seconds (its RC pair's time constant is ~20 s). A tick costs ~17 us of Python (7 of
    them setting the plant's limit): at 20 Hz the battery adds ~6 % to the CPU time of the square, the cheapest
    scenario (~100x real time), and 0.5 % to the tunnel's."""
    voltage_noise_v: float = 0.02
    """Standard deviation of the voltage reading's white noise [V] (an estimate: ~0.1 % of a 4S pack)."""
    current_noise_a: float = 0.1
    """Standard deviation of the current reading's white noise [A] (an estimate for a 100 A-range shunt)."""

    def __post_init__(self) -> None:
        check_real_fields(self, "battery", positive=True, unit=" [Hz]", names=("rate_hz",))
        check_real_fields(self, "battery", names=("voltage_noise_v", "current_noise_a"))
        check_at_most(self, "battery", rate_hz=1e3, voltage_noise_v=100.0, current_noise_a=1e3)


@dataclass(frozen=True)
class PowerSystem:
    """``vehicle.battery`` validated: the pack, the power draw and the power module."""

    battery: BatteryParams
    power: MotorPowerParams = field(default_factory=MotorPowerParams)
    monitor: PowerMonitorParams = field(default_factory=PowerMonitorParams)

    _PARTS = (("battery", BatteryParams), ("power", MotorPowerParams), ("monitor", PowerMonitorParams))

    @classmethod
    def parse(cls, data: Any, where: str = "battery") -> PowerSystem:
        """From the flat mapping of ``vehicle.battery``; a missing required key or an unknown one is a ConfigError
        naming it and the keys there are."""
        if isinstance(data, PowerSystem):
            return data
        if not isinstance(data, dict):
            raise ConfigError(
                f"{where} must be a mapping like {{cells: 4, capacity_mah: 850}}, got {type(data).__name__} {data!r}"
            )
        known = {f.name: part for part, c in cls._PARTS for f in dataclasses.fields(c)}
        unknown = sorted(str(k) for k in data if k not in known)
        if unknown:
            raise ConfigError(f"unknown key {unknown[0]!r} in {where}; expected one of {', '.join(known)}")
        for required in ("cells", "capacity_mah"):
            if required not in data:
                raise ConfigError(f"missing key {required!r} in {where} (a pack needs cells and capacity_mah)")
        split: dict[str, dict[str, Any]] = {part: {} for part, _ in cls._PARTS}
        for key, value in data.items():
            split[known[key]][key] = value
        return cls(  # their errors name battery.FIELD
            BatteryParams(**split["battery"]),
            MotorPowerParams(**split["power"]),
            PowerMonitorParams(**split["monitor"]),
        )

    def to_data(self) -> dict[str, Any]:
        """The flat mapping :meth:`parse` reads back into an equal object."""
        return {**to_dict(self.battery), **to_dict(self.power), **to_dict(self.monitor)}


class PowerMonitor(Sensor):
    """The pack on the plant and the power module reading it: see the module's docstring.

    Args:
        system: the pack, power draw and power module.
        vehicle: the simulated plant's parameters (its ``k_f``, ``c_m`` and ``rotor_speed_max``).
        plant: the simulated quadrotor whose rotor-speed limit the voltage sets (``set_max_rotor_speed``); None
            publishes the reading without limiting anything (a test bench).
        seed: the power module's noise stream.
        topic: where the reading goes.
    """

    name = "power_monitor"

    def __init__(
        self,
        system: PowerSystem,
        vehicle: QuadrotorParams,
        plant: Any = None,
        seed: int = 0,
        topic: str = Topics.BATTERY,
    ) -> None:
        if not isinstance(system, PowerSystem):
            raise TypeError(f"system must be a PowerSystem, got {type(system).__name__}")
        if plant is not None and not callable(getattr(plant, "set_max_rotor_speed", None)):
            raise TypeError(f"plant must have set_max_rotor_speed(omega_max) (a cufund.Quadrotor), got {plant!r}")
        self.system = system
        self.battery = Battery(system.battery)
        self.power = MotorPower(vehicle, system.power)
        self.plant = plant
        self.seed = seed
        self.rate_hz = system.monitor.rate_hz
        self.topic = topic
        self.nominal_voltage = system.battery.full_voltage
        """The pack voltage at which the plant reaches its ``rotor_speed_max`` [V]: the full pack's OCV."""
        self.reset()

    def reset(self) -> None:
        self.battery.reset()
        self._rng = np.random.default_rng(self.seed)
        self._t_last: float | None = None
        self.current_a = 0.0
        """The current drawn since the last tick [A] (true)."""
        self.voltage_v = self.battery.terminal_voltage(0.0)
        """The terminal voltage at the last tick [V] (true)."""
        self.min_voltage_v = math.inf
        """The lowest terminal voltage of the run so far while the pack was not empty [V] (true)."""
        self.max_rotor_speed = self.power.vehicle.rotor_speed_max
        """The rotor-speed limit set at the last tick [rad/s]."""
        if self.plant is not None:
            self.plant.set_max_rotor_speed(self.max_rotor_speed)

    def measure(self, t: float, truth: Odometry) -> BatteryStatus:
        bat = self.battery
        if self._t_last is not None:
            bat.step(t - self._t_last, self.current_a)
        self._t_last = t
        eta = getattr(self.plant, "rotor_efficiency", None)
        speeds = truth.rotor_speeds if truth.rotor_speeds is not None else np.zeros(4)
        power = self.power.electrical_power_w(speeds, None if eta is None else np.asarray(eta).reshape(-1))
        current = bat.current_for_power(power)
        voltage = bat.terminal_voltage(current)
        self.current_a, self.voltage_v = current, voltage
        if not bat.empty:  # an empty pack is cut off (0 V): the lowest voltage it gave is the one that counts
            self.min_voltage_v = min(self.min_voltage_v, voltage)
        limit = self.power.max_rotor_speed(voltage, self.nominal_voltage)
        if self.plant is not None and limit != self.max_rotor_speed:
            self.plant.set_max_rotor_speed(limit)
        self.max_rotor_speed = limit
        m = self.system.monitor
        noise_v, noise_i = self._rng.standard_normal(2)
        return BatteryStatus(
            t,
            max(voltage + m.voltage_noise_v * float(noise_v), 0.0),
            current + m.current_noise_a * float(noise_i),
            bat.soc,
            bat.consumed_mah,
            bat.params.cells,
        )

    def metrics(self, result: Any = None) -> dict[str, Any]:
        """``battery_used_mah`` (the charge drawn) and ``battery_min_voltage_v`` (the lowest terminal voltage before
        the pack ran empty), true values, for the run's metrics."""
        return {
            "battery_used_mah": float(self.battery.consumed_mah),
            "battery_min_voltage_v": None if math.isinf(self.min_voltage_v) else float(self.min_voltage_v),
        }

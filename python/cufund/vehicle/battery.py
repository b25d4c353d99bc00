"""The flight battery: a LiPo pack as an equivalent circuit (Thevenin model with one RC pair).

Per cell: an open-circuit voltage that depends on the state of charge, ``OCV(soc)``, in series with a resistance
``R0`` and one parallel ``R1 || C1`` pair (the polarisation that builds up within tens of seconds under load).
Cells are in series, so the pack's voltages and resistances are ``cells`` times a cell's and its capacitance a
``cells``-th; the time constant ``tau = R1 C1`` is the cell's. With the current ``I`` [A] (> 0 discharging)::

    d soc / dt  = -I / (3600 Q)             Q: capacity [Ah]
    d V_RC / dt = -V_RC / (R1 C1) + I / C1
    V           = OCV(soc) - I R0 - V_RC   terminal voltage

:meth:`Battery.step` integrates this exactly for a current held over the step (the charge is linear in time, the RC
pair's voltage relaxes exponentially towards ``I R1``), so the step size does not change the result.

The open-circuit voltage is the fit of Chen & Rincón-Mora, "Accurate electrical battery model capable of predicting
runtime and I-V performance", IEEE Trans. Energy Conversion 21(2), 2006, eq. (7), measured on a lithium-ion polymer
cell (TCL PL-383562, 850 mAh)::

    OCV(soc) = -1.031 exp(-35 soc) + 3.685 + 0.2156 soc - 0.1178 soc^2 + 0.3201 soc^3   [V]

4.10 V full, 3.80 V at half charge, and the knee below ~10 % where the voltage falls towards 2.65 V. The
default resistances are an estimate for a high-discharge (75C class) LiPo of ~1 Ah, stated at the fields.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, check_real_fields, from_dict, to_dict

__all__ = ["Battery", "BatteryParams", "lipo_ocv_per_cell"]


def lipo_ocv_per_cell(soc: float | np.ndarray) -> Any:
    """A LiPo cell's open-circuit voltage [V] at state of charge ``soc`` in [0, 1] (Chen & Rincón-Mora 2006,
    eq. 7; values outside [0, 1] are clipped to it)."""
    if isinstance(soc, (float, int)):  # the per-tick path, in scalar arithmetic
        x = min(max(float(soc), 0.0), 1.0)
        return -1.031 * math.exp(-35.0 * x) + 3.685 + x * (0.2156 + x * (-0.1178 + x * 0.3201))
    s = np.clip(soc, 0.0, 1.0)
    out = -1.031 * np.exp(-35.0 * s) + 3.685 + s * (0.2156 + s * (-0.1178 + s * 0.3201))
    return float(out) if np.ndim(out) == 0 else out


@dataclass(frozen=True)
class BatteryParams:
    """A LiPo pack: ``cells`` in series, each an equivalent circuit with the values below (per cell)."""

    cells: int
    """Cells in series (1 to 14: 1S to 14S)."""
    capacity_mah: float
    """Rated capacity [mAh], > 0 (the charge from full, soc = 1, to empty, soc = 0)."""
    r0_ohm: float = 0.010
    """Series (ohmic) resistance of one cell [ohm], >= 0. Default 10 mOhm: the DC internal resistance a charger
    reports for a ~1 Ah, 75C-class cell (an estimate; measure your pack's)."""
    r1_ohm: float = 0.005
    """Polarisation resistance of one cell's RC pair [ohm], >= 0 (0: no RC pair). Default 5 mOhm, an estimate of
    the same order as ``r0_ohm`` (Chen & Rincón-Mora's cell has 5 to 30 mOhm per ~1 Ah once scaled)."""
    c1_f: float = 4000.0
    """Capacitance of one cell's RC pair [F], > 0. Default 4000 F: ``tau = r1 c1 = 20 s``, the slow transient of
    Chen & Rincón-Mora's fit (tens of seconds)."""
    soc_initial: float = 1.0
    """State of charge at the start of a run, in (0, 1]."""

    def __post_init__(self) -> None:
        c = self.cells
        if isinstance(c, bool) or not isinstance(c, (int, np.integer)) or not 1 <= c <= 14:
            raise ConfigError(f"battery.cells must be an integer number of cells in series in [1, 14], got {c!r}")
        object.__setattr__(self, "cells", int(c))
        check_real_fields(self, "battery", positive=True, names=("capacity_mah", "c1_f"))
        check_real_fields(self, "battery", unit=" [ohm]", names=("r0_ohm", "r1_ohm"))
        check_real_fields(self, "battery", positive=True, names=("soc_initial",))
        if self.capacity_mah > 1e6:
            raise ConfigError(f"battery.capacity_mah must be at most 1e6 mAh, got {self.capacity_mah!r}")
        if self.r0_ohm > 10.0 or self.r1_ohm > 10.0:
            raise ConfigError(
                f"battery.r0_ohm and battery.r1_ohm are one cell's resistances, at most 10 ohm, got "
                f"{self.r0_ohm!r} and {self.r1_ohm!r}"
            )
        if self.soc_initial > 1.0:
            raise ConfigError(f"battery.soc_initial must be a state of charge in (0, 1], got {self.soc_initial!r}")

    @property
    def tau_s(self) -> float:
        """The RC pair's time constant r1 c1 [s]."""
        return self.r1_ohm * self.c1_f

    @property
    def full_voltage(self) -> float:
        """The pack's open-circuit voltage when full [V]."""
        return self.cells * lipo_ocv_per_cell(1.0)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BatteryParams:
        """From a mapping with this class's field names; unknown keys raise, naming the known ones."""
        return from_dict(cls, data, "battery")

    def to_dict(self) -> dict[str, Any]:
        return to_dict(self)


class Battery:
    """The pack's state (state of charge, the RC pair's voltage, the charge drawn) and its exact integration.

    Every voltage and resistance here is the pack's (``cells`` times a cell's)."""

    def __init__(self, params: BatteryParams) -> None:
        if not isinstance(params, BatteryParams):
            raise TypeError(f"params must be a cufund.vehicle.battery.BatteryParams, got {type(params).__name__}")
        self.params = params
        n = params.cells
        self.r0 = n * params.r0_ohm
        """Pack series resistance [ohm]."""
        self.r1 = n * params.r1_ohm
        """Pack RC-pair resistance [ohm]."""
        self._charge_as = params.capacity_mah * 3.6  # [A s]
        self.reset()

    def reset(self) -> None:
        """Back to ``soc_initial`` with the RC pair relaxed and nothing drawn."""
        self.soc = self.params.soc_initial
        """State of charge in [0, 1]."""
        self.v_rc = 0.0
        """Voltage across the pack's RC pairs [V]."""
        self.consumed_mah = 0.0
        """Charge drawn since the reset [mAh]."""

    @property
    def empty(self) -> bool:
        """Nothing left to draw (soc = 0)."""
        return self.soc <= 0.0

    def ocv(self) -> float:
        """The pack's open-circuit voltage now [V]."""
        return self.params.cells * lipo_ocv_per_cell(self.soc)

    def terminal_voltage(self, current_a: float) -> float:
        """V = OCV(soc) - I R0 - V_RC [V] while ``current_a`` [A] flows (0 once empty)."""
        if self.empty:
            return 0.0
        return self.ocv() - current_a * self.r0 - self.v_rc

    def current_for_power(self, power_w: float) -> float:
        """The current [A] at which the pack delivers ``power_w`` [W] at its terminals: the smaller root of
        ``I (E - I R0) = P`` with ``E = OCV - V_RC``; past the most the pack can give (``E^2 / (4 R0)``, at
        ``I = E / (2 R0)``) it is that current. 0 once empty or for ``power_w <= 0``."""
        if not math.isfinite(power_w):
            raise ValueError(f"power_w must be finite [W], got {power_w!r}")
        if self.empty or power_w <= 0.0:
            return 0.0
        e = self.ocv() - self.v_rc
        if e <= 0.0:
            return 0.0
        if self.r0 == 0.0:
            return power_w / e
        disc = e * e - 4.0 * self.r0 * power_w
        if disc <= 0.0:
            return e / (2.0 * self.r0)
        return 2.0 * power_w / (e + math.sqrt(disc))  # (E - sqrt(disc)) / (2 R0), without the cancellation

    def step(self, dt: float, current_a: float) -> None:
        """Advances ``dt`` [s] with ``current_a`` [A] held (> 0 discharging), exactly. The charge stops at empty."""
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"dt must be a finite duration >= 0 [s], got {dt!r}")
        if not math.isfinite(current_a):
            raise ValueError(f"current_a must be finite [A], got {current_a!r}")
        if dt == 0.0:
            return
        drawn = current_a * dt  # [A s]
        left = self.soc * self._charge_as
        if drawn > left:
            drawn = left
        self.soc = max(0.0, (left - drawn) / self._charge_as)
        self.consumed_mah += drawn / 3.6
        tau = self.params.tau_s
        if tau > 0.0:
            decay = math.exp(-dt / tau)
            self.v_rc = self.v_rc * decay - current_a * self.r1 * math.expm1(-dt / tau)
        else:
            self.v_rc = current_a * self.r1

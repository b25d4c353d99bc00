"""The battery's equivalent circuit and the rotors' power model against independent solutions: the circuit's closed
form and scipy's ODE integrator, the constant-power load's quadratic, and the presets' constants by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cufund.core.config import ConfigError
from cufund.vehicle import presets
from cufund.vehicle.battery import Battery, BatteryParams, lipo_ocv_per_cell
from cufund.vehicle.motor_power import MotorPower, MotorPowerParams

PACK = BatteryParams(cells=4, capacity_mah=850.0, r0_ohm=0.012, r1_ohm=0.006, c1_f=3000.0)


def _ocv(soc: float) -> float:
    """Chen & Rincon-Mora (2006) eq. 7, written out again."""
    return -1.031 * math.exp(-35 * soc) + 3.685 + 0.2156 * soc - 0.1178 * soc**2 + 0.3201 * soc**3


def test_ocv_curve_is_the_published_fit() -> None:
    for soc in (0.0, 0.03, 0.1, 0.5, 0.9, 1.0):
        assert lipo_ocv_per_cell(soc) == pytest.approx(_ocv(soc), abs=1e-12)
    s = np.linspace(0.0, 1.0, 1001)
    assert np.all(np.diff(lipo_ocv_per_cell(s)) > 0)  # charge raises the voltage everywhere
    assert lipo_ocv_per_cell(1.0) == pytest.approx(4.1029, abs=1e-4)
    assert lipo_ocv_per_cell(-0.5) == lipo_ocv_per_cell(0.0)


def test_constant_current_discharge_matches_the_closed_form() -> None:
    """soc falls linearly, V_RC rises as I R1 (1 - exp(-t / tau)); V = n OCV(soc) - I R0 - V_RC."""
    current, n = 20.0, PACK.cells
    bat = Battery(PACK)
    tau = PACK.r1_ohm * PACK.c1_f
    q_as = PACK.capacity_mah * 3.6
    t, dt = 0.0, 0.37
    while t < 140.0:
        bat.step(dt, current)
        t += dt
        soc = 1.0 - current * t / q_as
        v_rc = n * current * PACK.r1_ohm * (1.0 - math.exp(-t / tau))
        v = n * _ocv(soc) - current * n * PACK.r0_ohm - v_rc
        assert bat.soc == pytest.approx(soc, abs=1e-12)
        assert bat.v_rc == pytest.approx(v_rc, rel=1e-9)
        assert bat.terminal_voltage(current) == pytest.approx(v, abs=1e-9)
    assert bat.consumed_mah == pytest.approx(current * t / 3.6, rel=1e-12)


def test_step_is_exact_whatever_its_size() -> None:
    a, b = Battery(PACK), Battery(PACK)
    a.step(60.0, 15.0)
    for _ in range(6000):
        b.step(0.01, 15.0)
    assert b.soc == pytest.approx(a.soc, abs=1e-12)
    assert b.v_rc == pytest.approx(a.v_rc, rel=1e-10)


def test_piecewise_current_matches_scipy() -> None:
    """A current profile that changes every few seconds, against solve_ivp on the circuit's ODE."""
    n, r1, c1 = PACK.cells, PACK.cells * PACK.r1_ohm, PACK.c1_f / PACK.cells
    q_as = PACK.capacity_mah * 3.6
    profile = [(5.0, 2.0), (12.0, 25.0), (3.0, 0.0), (20.0, 40.0), (8.0, 10.0)]  # (duration [s], current [A])
    bat = Battery(PACK)
    y = np.array([1.0, 0.0])
    for duration, current in profile:
        bat.step(duration, current)
        sol = solve_ivp(
            lambda _t, s, i=current: [-i / q_as, -s[1] / (r1 * c1) + i / c1],
            (0.0, duration),
            y,
            rtol=1e-11,
            atol=1e-12,
        )
        y = sol.y[:, -1]
        assert bat.soc == pytest.approx(y[0], abs=1e-9)
        assert bat.v_rc == pytest.approx(y[1], abs=1e-7)
        assert bat.terminal_voltage(current) == pytest.approx(
            n * _ocv(y[0]) - current * n * PACK.r0_ohm - y[1], abs=1e-6
        )


def test_constant_power_current_solves_the_load() -> None:
    bat = Battery(PACK)
    bat.step(30.0, 20.0)
    for power in (1.0, 150.0, 800.0):
        i = bat.current_for_power(power)
        assert i * bat.terminal_voltage(i) == pytest.approx(power, rel=1e-10)
    e = bat.ocv() - bat.v_rc
    r0 = PACK.cells * PACK.r0_ohm
    p_max = e * e / (4 * r0)  # the most a source E behind R0 delivers, at I = E / (2 R0)
    assert bat.current_for_power(2 * p_max) == pytest.approx(e / (2 * r0))
    assert bat.current_for_power(0.0) == 0.0


def test_discharge_stops_at_empty() -> None:
    bat = Battery(BatteryParams(cells=1, capacity_mah=100.0))
    bat.step(3600.0, 1.0)  # ten times the charge
    assert bat.empty and bat.soc == 0.0
    assert bat.consumed_mah == pytest.approx(100.0)
    assert bat.terminal_voltage(1.0) == 0.0 and bat.current_for_power(10.0) == 0.0
    bat.reset()
    assert bat.soc == 1.0 and bat.consumed_mah == 0.0 and bat.v_rc == 0.0


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"cells": 0, "capacity_mah": 850}, "battery.cells"),
        ({"cells": 2.5, "capacity_mah": 850}, "battery.cells"),
        ({"cells": 4, "capacity_mah": 0}, "battery.capacity_mah"),
        ({"cells": 4, "capacity_mah": 850, "r0_ohm": -0.1}, "battery.r0_ohm"),
        ({"cells": 4, "capacity_mah": 850, "c1_f": math.nan}, "battery.c1_f"),
        ({"cells": 4, "capacity_mah": 850, "soc_initial": 1.5}, "battery.soc_initial"),
    ],
)
def test_params_name_the_bad_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        BatteryParams(**kwargs)


def test_motor_power_from_the_preset_constants() -> None:
    """Hover: four rotors each carry m g / 4 at omega_h = sqrt(m g / (4 k_f)) and take c_m (m g / 4) omega_h."""
    p = presets.cu_astro()
    mp = MotorPower(p, MotorPowerParams(efficiency=0.8, avionics_w=7.0))
    weight = p.mass * p.gravity
    omega_h = math.sqrt(weight / (4 * p.k_f))
    shaft = 4 * p.c_m * (weight / 4) * omega_h
    assert mp.hover_power_w() == pytest.approx(shaft / 0.8 + 7.0, rel=1e-12)
    # a stopped rotor (efficiency 0) takes nothing
    speeds = np.array([1000.0, 1500.0, 2000.0, 2500.0])
    eta = np.array([1.0, 1.0, 0.0, 1.0])
    expected = p.c_m * p.k_f * (1000.0**3 + 1500.0**3 + 2500.0**3) / 0.8 + 7.0
    assert mp.electrical_power_w(speeds, eta) == pytest.approx(expected, rel=1e-12)


def test_max_rotor_speed_scales_with_voltage() -> None:
    p = presets.cu_astro()
    mp = MotorPower(p)
    assert mp.max_rotor_speed(16.0, 16.0) == p.rotor_speed_max
    assert mp.max_rotor_speed(12.0, 16.0) == pytest.approx(0.75 * p.rotor_speed_max)
    assert mp.max_rotor_speed(20.0, 16.0) == p.rotor_speed_max  # never above the preset's
    assert mp.max_rotor_speed(0.0, 16.0) == p.rotor_speed_min
    with pytest.raises(ConfigError, match="battery.efficiency"):
        MotorPowerParams(efficiency=1.2)

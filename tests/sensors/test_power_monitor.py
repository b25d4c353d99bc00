"""The battery in a run: the power monitor against scipy's solution of the constant-power circuit, a hover flight
against the energy budget computed by hand from the preset, the rotor-speed limit under voltage sag, and a
scenario without ``vehicle.battery`` untouched."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cufund.core.config import ConfigError
from cufund.core.messages import Odometry, Topics
from cufund.scenarios import ScenarioConfig, load_scenario
from cufund.scenarios.build import build_simulation, run_built, run_scenario
from cufund.sensors.power_monitor import PowerMonitor, PowerSystem
from cufund.vehicle import presets
from cufund.vehicle.battery import lipo_ocv_per_cell


class _Plant:
    """Stands in for the quadrotor: keeps the limits it is given."""

    def __init__(self) -> None:
        self.limits: list[float] = []

    def set_max_rotor_speed(self, omega_max: float) -> None:
        self.limits.append(float(omega_max))


def _truth(t: float, omega: float) -> Odometry:
    z = np.zeros(3)
    return Odometry(t, z, z, np.array([1.0, 0, 0, 0]), z, z, z, np.full(4, omega))


def test_parse_splits_the_flat_keys_and_names_bad_ones() -> None:
    s = PowerSystem.parse({"cells": 6, "capacity_mah": 1300, "efficiency": 0.8, "rate_hz": 20, "r0_ohm": 0.004})
    assert (s.battery.cells, s.battery.capacity_mah, s.battery.r0_ohm) == (6, 1300.0, 0.004)
    assert (s.power.efficiency, s.monitor.rate_hz) == (0.8, 20.0)
    assert PowerSystem.parse(s.to_data()) == s
    with pytest.raises(ConfigError, match="unknown key 'voltage'.*expected one of cells, capacity_mah"):
        PowerSystem.parse({"cells": 4, "capacity_mah": 850, "voltage": 16.8})
    with pytest.raises(ConfigError, match="missing key 'cells'"):
        PowerSystem.parse({"capacity_mah": 850})
    with pytest.raises(ConfigError, match="battery.rate_hz"):
        PowerSystem.parse({"cells": 4, "capacity_mah": 850, "rate_hz": 0})


def test_constant_power_discharge_matches_scipy() -> None:
    """Rotors held at one speed draw a constant power P: I solves I (OCV(soc) - V_RC - I R0) = P. The monitor
    (current held between its 50 Hz ticks) against solve_ivp on that differential-algebraic system."""
    vehicle = presets.cu_astro()
    system = PowerSystem.parse({"cells": 4, "capacity_mah": 300, "avionics_w": 12, "r0_ohm": 0.012})
    plant = _Plant()
    mon = PowerMonitor(system, vehicle, plant, seed=1)
    omega = 2200.0
    power = 4 * vehicle.c_m * vehicle.k_f * omega**3 / 0.75 + 12.0
    n, q_as = 4, 300 * 3.6
    r0, r1, c1 = n * 0.012, n * system.battery.r1_ohm, system.battery.c1_f / n

    def current(soc: float, v_rc: float) -> float:
        e = n * lipo_ocv_per_cell(soc) - v_rc
        return (e - math.sqrt(e * e - 4 * r0 * power)) / (2 * r0)

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        i = current(y[0], y[1])
        return [-i / q_as, -y[1] / (r1 * c1) + i / c1]

    t_end = 30.0  # down to ~25 % charge
    ref = solve_ivp(rhs, (0.0, t_end), [1.0, 0.0], rtol=1e-10, atol=1e-12, dense_output=True)
    for k in range(int(t_end * 50) + 1):
        msg = mon.measure(k / 50, _truth(k / 50, omega))
    soc, v_rc = ref.sol(t_end)
    i = current(soc, v_rc)
    # the current held over a tick lags the rising current by half a tick: |dI/dt| dt / 2 * t / Q ~ 3e-5
    assert mon.battery.soc == pytest.approx(soc, abs=1e-4)
    assert mon.current_a == pytest.approx(i, rel=1e-3)
    assert mon.voltage_v == pytest.approx(n * lipo_ocv_per_cell(soc) - v_rc - i * r0, abs=2e-3)
    assert msg.remaining == mon.battery.soc and msg.cells == 4
    assert msg.consumed_mah == pytest.approx((1.0 - soc) * 300, rel=1e-3)
    # the limit follows the sagging voltage: rotor_speed_max * V / V_full, falling
    v_full = 4 * lipo_ocv_per_cell(1.0)
    assert plant.limits[-1] == pytest.approx(vehicle.rotor_speed_max * mon.voltage_v / v_full, rel=1e-12)
    assert plant.limits[0] == vehicle.rotor_speed_max and plant.limits[-1] < plant.limits[1] < plant.limits[0]


def test_the_reading_is_noisy_and_seeded() -> None:
    vehicle = presets.cu_astro()
    system = PowerSystem.parse({"cells": 4, "capacity_mah": 5000, "voltage_noise_v": 0.05, "current_noise_a": 0.2})

    def readings(seed: int) -> np.ndarray:
        mon = PowerMonitor(system, vehicle, None, seed)
        out = []
        for k in range(2000):
            m = mon.measure(k / 50, _truth(k / 50, 2000.0))
            out.append((m.voltage_v - mon.voltage_v, m.current_a - mon.current_a))
        return np.array(out)

    a, b = readings(3), readings(3)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, readings(4))
    assert np.std(a[:, 0]) == pytest.approx(0.05, rel=0.1)
    assert np.std(a[:, 1]) == pytest.approx(0.2, rel=0.1)


# -- in a scenario (needs the plant's set_max_rotor_speed) -------------------------------------------------------


def _hover(capacity_mah: float, cells: int = 4, avionics_w: float = 12.0, hover_s: float = 1000.0) -> ScenarioConfig:
    return load_scenario(
        "square",
        {
            "vehicle": {
                "preset": "cu_astro",
                "battery": {"cells": cells, "capacity_mah": capacity_mah, "avionics_w": avionics_w},
            },
            "trajectory.waypoints": [[0, 0, 1.5], [0, 0, 1.6]],
            "trajectory.hover_s": hover_s,
            "duration": 2 * hover_s,
            "failsafe": "off",  # the plant's endurance: no battery failsafe lands it early
        },
    )


def test_hover_endurance_matches_the_energy_budget() -> None:
    """Hover until the pack cannot hold the vehicle up; the time aloft against the budget by hand: the pack's
    energy at the LiPo nominal 3.7 V per cell over the hover power of the preset's rotors."""
    capacity_mah, cells, avionics_w, efficiency = 300.0, 4, 12.0, 0.75
    p = presets.cu_astro()
    weight = p.mass * p.gravity
    omega_h = math.sqrt(weight / (4 * p.k_f))  # 1986 rad/s
    shaft_w = 4 * (p.c_m * p.k_f) * omega_h**3  # drag torque k_m omega^2 times omega, four rotors: 195 W
    electric_w = shaft_w / efficiency + avionics_w  # 272 W
    energy_j = capacity_mah / 1000 * 3600 * cells * 3.7  # 16.0 kJ
    budget_s = energy_j / electric_w  # 58.8 s

    run = run_scenario(_hover(capacity_mah, cells, avionics_w, hover_s=1000.0))
    t, z = run.result.states["t"], run.result.states["p_W"][:, 2]
    up = np.flatnonzero(z > 1.4)
    assert len(up), "never reached the hover height"
    t_up = t[up[0]]
    t_off = t[np.flatnonzero(z > 0.05)[0]]
    fell = np.flatnonzero((t > t_up) & (z < 1.0))
    assert len(fell), f"still aloft at {t[-1]:.1f} s ({run.result.message})"
    aloft_s = t[fell[0]] - t_off
    bat = run.result.topics[str(Topics.BATTERY)]
    assert aloft_s == pytest.approx(budget_s, rel=0.10), (aloft_s, budget_s)
    assert float(np.min(bat["remaining"])) < 0.05  # it came down because the pack was spent
    assert run.metrics["battery_used_mah"] == pytest.approx(capacity_mah, rel=0.05)
    assert 2.0 * cells < run.metrics["battery_min_voltage_v"] < 3.5 * cells  # the knee, before the cut-off


def test_voltage_sag_lowers_the_rotor_speed_limit() -> None:
    built = build_simulation(_hover(850.0, hover_s=5.0).replace(duration=8.0))
    quad = built.simulator.vehicle
    mon = next(c for c in built.simulator.components if isinstance(c, PowerMonitor))
    sim = built.simulator
    sim.reset()
    assert float(np.asarray(quad.max_rotor_speed).reshape(-1)[0]) == quad.params.rotor_speed_max
    sim.advance_to(6.0)  # hovering: ~18 A
    limit = float(np.asarray(quad.max_rotor_speed).reshape(-1)[0])
    expected = quad.params.rotor_speed_max * mon.voltage_v / (4 * lipo_ocv_per_cell(1.0))
    assert limit == pytest.approx(expected, rel=1e-12)
    assert limit < 0.97 * quad.params.rotor_speed_max  # the pack sags under the hover load
    quad.step(0.01, np.full(4, quad.params.rotor_speed_max))  # a full command is clamped to the sagged limit
    assert np.all(quad.state.rotor_speeds <= limit + 1e-9)


def test_no_battery_changes_nothing() -> None:
    """``vehicle: cu_astro`` and ``vehicle: {preset: cu_astro}`` fly the same run, without a power monitor."""
    base = load_scenario("square", {"duration": 6.0})
    mapped = base.replace(vehicle={"preset": "cu_astro"})
    assert base.power_system() is None and mapped.power_system() is None
    assert mapped.vehicle_params() == base.vehicle_params()
    builts = [build_simulation(c) for c in (base, mapped)]
    for b in builts:
        assert not any(isinstance(c, PowerMonitor) for c in b.simulator.components)
    runs = [run_built(b) for b in builts]
    for r in runs:
        assert "battery_used_mah" not in r.metrics and str(Topics.BATTERY) not in r.result.topics
    np.testing.assert_array_equal(runs[0].result.states["p_W"], runs[1].result.states["p_W"])
    np.testing.assert_array_equal(runs[0].result.states["rotor_speeds"], runs[1].result.states["rotor_speeds"])


def test_set_on_a_preset_string_makes_the_mapping() -> None:
    c = load_scenario("square", ["vehicle.battery.cells=4", "vehicle.battery.capacity_mah=850"])
    assert c.vehicle == {"preset": "cu_astro", "battery": {"cells": 4, "capacity_mah": 850}}
    assert c.power_system() is not None and c.power_system().battery.cells == 4
    assert ScenarioConfig.from_dict(c.to_dict()) == c
    with pytest.raises(ConfigError, match="missing key 'capacity_mah'"):
        load_scenario("square", ["vehicle.battery.cells=4"])
    with pytest.raises(ConfigError, match="preset must be one of"):
        load_scenario("square", ["vehicle.preset=cf2"])

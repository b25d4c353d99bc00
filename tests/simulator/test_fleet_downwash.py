"""Rotor downwash in a fleet: the thrust a vehicle hovering below another loses follows the round-jet model's curve
(computed here by hand from its published constants), and a vehicle laterally clear of the other feels none."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cufund.simulator import Simulator
from cufund.simulator.fleet import FleetMember, FleetSimulator
from cufund.vehicle import presets
from cufund.vehicle.quadrotor import Quadrotor
from cufund.worlds.downwash import DownwashConfig, jet_speed

RHO = 1.225
B, S = 5.8, 0.094  # Hussein, Capp & George (1994): centreline decay and spreading rate of a round jet


def _hovering(p_W):
    quad = Quadrotor(presets.cu_astro())
    quad.hover(np.asarray(p_W, dtype=float))
    return quad


def _pair(p_low, p_high, config=None):
    params = presets.cu_astro()
    radius = 0.385 * params.arm_length
    members = [
        FleetMember("low", Simulator(_hovering(p_low)), rotor_radius_m=radius),
        FleetMember("high", Simulator(_hovering(p_high)), rotor_radius_m=radius),
    ]
    fleet = FleetSimulator(members, downwash=config or DownwashConfig())
    fleet.reset()
    return fleet, members, params, radius


def _expected_loss(params, radius, dz):
    """The model by hand: the upper vehicle's jet (momentum flux T / rho) at each lower rotor's centre, straight
    below the upper vehicle (the rotor's distance from the axis is its arm), F = 1/2 rho A_r u^2 per rotor."""
    T = params.mass * params.gravity  # hover thrust [N]
    u_j = 2 * math.sqrt(T / (2 * RHO * 4 * math.pi * radius**2))
    u_c = min(u_j, B * math.sqrt(4 * T / (math.pi * RHO)) / dz)
    d_j = math.sqrt(4 * (T / RHO) / (math.pi * u_j**2))
    b = max(d_j / 2, S * dz)
    r = np.linalg.norm(params.rotor_positions()[:, :2], axis=1)
    u = u_c * np.exp(-math.log(2) * (r / b) ** 2)
    return float(np.sum(0.5 * RHO * math.pi * radius**2 * u**2))


@pytest.mark.parametrize("dz", [1.0, 2.0, 4.0, 8.0])
def test_thrust_loss_below_another_follows_the_curve(dz):
    fleet, members, params, radius = _pair((0, 0, 2.0), (0, 0, 2.0 + dz))
    force = fleet.downwash_forces["low"]
    assert force[0] == pytest.approx(0.0, abs=1e-12) and force[1] == pytest.approx(0.0, abs=1e-12)
    assert -force[2] == pytest.approx(_expected_loss(params, radius, dz), rel=1e-9)
    assert np.all(fleet.downwash_forces["high"] == 0.0)  # nothing blows upwards
    # the plant feels it: one physics step later the lower vehicle accelerates down by F / m, the upper not
    fleet.advance_to(0.001)
    low, high = (m.simulator.vehicle for m in members)
    assert low.accel_W[2] == pytest.approx(force[2] / params.mass, rel=0.02, abs=1e-3)
    assert abs(high.accel_W[2]) < 1e-3


def test_a_new_run_starts_without_the_last_runs_downwash():
    """The plant holds the downwash the fleet set on it; a reset or a new run takes it off before setting the new."""
    fleet, members, *_ = _pair((0, 0, 2.0), (0, 0, 3.0))
    low = members[0].simulator.vehicle
    force = fleet.downwash_forces["low"]
    assert force[2] < 0 and np.array_equal(low.force_ext_W, force)
    fleet.reset()
    assert np.array_equal(low.force_ext_W, force)
    fleet.run(0.01)
    assert np.array_equal(low.force_ext_W, fleet.downwash_forces["low"])


def test_far_field_decays_as_the_inverse_square():
    """Centreline speed ~ 1/s, so the force on a vehicle well below goes as 1/s^2."""
    f = {}
    for dz in (10.0, 20.0):
        fleet, *_ = _pair((0, 0, 1.0), (0, 0, 1.0 + dz))
        f[dz] = -fleet.downwash_forces["low"][2]
    assert f[20.0] / f[10.0] == pytest.approx(0.25, rel=0.02)


def test_half_width_grows_linearly():
    T = 5.0
    for s in (3.0, 6.0):
        centre = float(jet_speed(T, s, 0.0, 0.04))
        assert float(jet_speed(T, s, S * s, 0.04)) == pytest.approx(centre / 2, rel=1e-12)


def test_none_when_laterally_clear():
    """3 m to the side of the upper vehicle the lower one is outside its jet: exactly no force, and it hovers bit
    for bit as it does alone."""
    fleet, members, *_ = _pair((3.0, 0, 2.0), (0, 0, 3.0))
    assert np.all(fleet.downwash_forces["low"] == 0.0)
    fleet.advance_to(0.5)
    alone = Simulator(_hovering((3.0, 0, 2.0)))
    alone.reset()
    alone.advance_to(0.5)
    a, b = alone.result().states, members[0].simulator.result().states
    for k in a:
        assert np.array_equal(a[k], b[k]), k


def test_off_by_default_and_bad_config_named():
    assert DownwashConfig.parse(None) is None and DownwashConfig.parse(False) is None
    from cufund.core.config import ConfigError

    with pytest.raises(ConfigError, match="downwash.thrust_loss_coefficient"):
        DownwashConfig.parse({"thrust_loss_coefficient": -1})
    with pytest.raises(ConfigError, match="unknown key 'rho'"):
        DownwashConfig.parse({"rho": 1.2})


def test_the_fleet_skips_only_pairs_out_of_every_jet():
    """The fleet evaluates only the jets that may reach a vehicle; its forces equal every jet summed."""
    from cufund.geometry import quat_from_rotvec, quat_to_matrix
    from cufund.worlds.downwash import downwash_force

    rng = np.random.default_rng(3)
    params = presets.cu_astro()
    radius = 0.385 * params.arm_length
    members = []
    for k in range(8):
        quad = _hovering(rng.uniform((-1.5, -1.5, 1.0), (1.5, 1.5, 6.0)))
        quad.state.q[:] = quat_from_rotvec(rng.normal(0, 0.3, 3))
        members.append(FleetMember(f"v{k}", Simulator(quad), rotor_radius_m=radius))
    fleet = FleetSimulator(members, downwash=DownwashConfig())
    fleet.reset()
    forces = fleet.downwash_forces
    states = [m.simulator.vehicle.state for m in members]
    thrust = params.k_f * np.sum(states[0].rotor_speeds ** 2)
    felt = 0
    for i, m in enumerate(members):
        R_i = quat_to_matrix(states[i].q, normalize=True)
        sources = [
            (thrust, states[j].p, quat_to_matrix(states[j].q, normalize=True), radius) for j in range(8) if j != i
        ]
        expected = downwash_force(DownwashConfig(), sources, states[i].p + params.rotor_positions() @ R_i.T, radius)
        assert np.allclose(forces[m.name], expected, rtol=1e-12, atol=1e-15), m.name
        felt += bool(np.any(expected != 0))
    assert 0 < felt < 8  # some under a jet, some not: both branches exercised

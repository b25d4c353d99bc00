"""The plant's rotor efficiency and rotor speed limit (issue 30's contract with the battery and the motor faults):
their effect against the closed-form wrench and the motor lag, persistence, reset, pickling and bad input."""

import dataclasses
import math
import pickle

import numpy as np
import pytest

from cufund.vehicle import Quadrotor, QuadrotorBatch, presets


@pytest.fixture
def params():
    return dataclasses.replace(presets.cu_astro(), ground_plane=False)


def _hovering(params):
    quad = Quadrotor(params)
    quad.hover((0.0, 0.0, 5.0))
    return quad


def test_defaults_are_nominal_and_reset_restores_them(params):
    quad = Quadrotor(params)
    np.testing.assert_array_equal(quad.rotor_efficiency, np.ones(4))
    assert quad.max_rotor_speed == params.rotor_speed_max
    quad.set_rotor_efficiency([1.0, 0.5, 0.0, 1.0])
    quad.set_max_rotor_speed(1000.0)
    quad.step(0.01, np.full(4, 500.0))
    np.testing.assert_array_equal(quad.rotor_efficiency, [1.0, 0.5, 0.0, 1.0])  # persists across steps
    assert quad.max_rotor_speed == 1000.0
    quad.reset()
    np.testing.assert_array_equal(quad.rotor_efficiency, np.ones(4))
    assert quad.max_rotor_speed == params.rotor_speed_max


def test_efficiency_scales_thrust_and_drag_torque_per_rotor(params):
    """With rotor speeds held at hover, eta = (e1..e4) gives the wrench of thrusts k_f w^2 e_i through the
    allocation matrix: the acceleration and angular acceleration right after the step match it."""
    eta = np.array([1.0, 0.8, 0.0, 0.6])
    quad = _hovering(params)
    quad.set_rotor_efficiency(eta)
    wh = params.hover_rotor_speed
    quad.step(1e-9, np.full(4, wh))  # a step short enough that the state has not moved
    f = params.k_f * wh**2 * eta
    wrench = params.allocation_matrix() @ f
    J = params.inertia_matrix
    np.testing.assert_allclose(quad.accel_W, [0.0, 0.0, wrench[0] / params.mass - params.gravity], atol=1e-6)
    np.testing.assert_allclose(quad.alpha_B, np.linalg.solve(J, wrench[1:]), rtol=1e-6, atol=1e-6)


def test_uniform_efficiency_gives_the_closed_form_sink_rate(params):
    quad = _hovering(params)
    quad.set_rotor_efficiency(np.full(4, 0.81))
    wh = params.hover_rotor_speed
    for _ in range(100):
        quad.step(1e-3, np.full(4, wh))
    a = 0.81 * params.gravity - params.gravity  # no drag at these speeds? body drag slows it: compare early
    assert quad.state.v[2] == pytest.approx(a * 0.1, rel=2e-3)


def test_max_rotor_speed_clamps_the_command_through_the_motor_lag(params):
    quad = Quadrotor(params)
    quad.state.p[:] = (0.0, 0.0, 100.0)
    limit = 0.6 * params.rotor_speed_max
    quad.set_max_rotor_speed(limit)
    t = 0.0
    for _ in range(50):
        quad.step(1e-3, np.full(4, params.rotor_speed_max))
        t += 1e-3
    np.testing.assert_allclose(quad.state.rotor_speeds, limit * (1 - math.exp(-t / params.tau_m)), rtol=1e-7)


def test_batch_per_vehicle_settings_equal_single_vehicles_bit_for_bit(params):
    etas = np.array([[1.0, 1.0, 1.0, 1.0], [0.9, 1.0, 0.7, 1.0], [0.0, 1.0, 1.0, 1.0]])
    limits = np.array([params.rotor_speed_max, 2000.0, 1500.0])
    batch = QuadrotorBatch(params, 3)
    batch.hover(np.array([0.0, 0.0, 5.0]))
    batch.set_rotor_efficiency(etas)
    batch.set_max_rotor_speed(limits)
    singles = []
    for k in range(3):
        q = _hovering(params)
        q.set_rotor_efficiency(etas[k])
        q.set_max_rotor_speed(limits[k])
        singles.append(q)
    cmd = np.tile(np.linspace(1500.0, 2600.0, 4), (3, 1))
    for _ in range(200):
        batch.step(2e-3, cmd)
        for q in singles:
            q.step(2e-3, cmd[0])
    for k, q in enumerate(singles):
        np.testing.assert_array_equal(batch.p[k], q.state.p)
        np.testing.assert_array_equal(batch.q[k], q.state.q)
    assert not np.array_equal(batch.p[0], batch.p[1])


def test_nominal_settings_written_explicitly_change_nothing(params):
    a, b = _hovering(params), _hovering(params)
    b.set_rotor_efficiency(np.ones(4))
    b.set_max_rotor_speed(params.rotor_speed_max)
    cmd = np.array([2000.0, 2100.0, 2050.0, 1990.0])
    for _ in range(300):
        a.step(1e-3, cmd)
        b.step(1e-3, cmd)
    np.testing.assert_array_equal(a.state.as_vector(), b.state.as_vector())


def test_pickling_keeps_efficiency_and_limit(params):
    quad = _hovering(params)
    quad.set_rotor_efficiency([0.5, 1.0, 1.0, 0.25])
    quad.set_max_rotor_speed(1234.0)
    copy = pickle.loads(pickle.dumps(quad))
    np.testing.assert_array_equal(copy.rotor_efficiency, [0.5, 1.0, 1.0, 0.25])
    assert copy.max_rotor_speed == 1234.0
    cmd = np.full(4, 2000.0)
    for _ in range(50):
        quad.step(1e-3, cmd)
        copy.step(1e-3, cmd)
    np.testing.assert_array_equal(quad.state.as_vector(), copy.state.as_vector())


def test_views_are_read_only(params):
    quad = Quadrotor(params)
    with pytest.raises(ValueError, match="read-only"):
        quad.rotor_efficiency[0] = 0.5
    batch = QuadrotorBatch(params, 2)
    with pytest.raises(ValueError, match="read-only"):
        batch.max_rotor_speed[0] = 5.0


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ([1.0, 1.0, 1.0, 1.5], r"rotor_efficiency must be in \[0, 1\].*rotor 4"),
        ([1.0, -0.1, 1.0, 1.0], r"rotor_efficiency must be in \[0, 1\].*rotor 2"),
        ([1.0, np.nan, 1.0, 1.0], "rotor_efficiency must be finite"),
        ([1.0, 1.0, 1.0], r"rotor_efficiency must have shape \(4,\)"),
        ("abc", "rotor_efficiency must be an array of real numbers"),
    ],
)
def test_bad_efficiency_is_refused_naming_the_field(params, value, match):
    quad = Quadrotor(params)
    with pytest.raises(ValueError, match=match):
        quad.set_rotor_efficiency(value)
    np.testing.assert_array_equal(quad.rotor_efficiency, np.ones(4))


@pytest.mark.parametrize(
    ("value", "match"),
    [
        (np.nan, "max_rotor_speed must be a finite number >= rotor_speed_min"),
        (-1.0, "max_rotor_speed must be a finite number >= rotor_speed_min"),
        ([1.0, 2.0], "max_rotor_speed must be a scalar"),
        (True, "max_rotor_speed must be a finite number"),
    ],
)
def test_bad_rotor_speed_limit_is_refused_naming_the_field(params, value, match):
    quad = Quadrotor(params)
    with pytest.raises(ValueError, match=match):
        quad.set_max_rotor_speed(value)
    assert quad.max_rotor_speed == params.rotor_speed_max


def test_batch_shapes(params):
    batch = QuadrotorBatch(params, 3)
    assert batch.rotor_efficiency.shape == (3, 4)
    assert batch.max_rotor_speed.shape == (3,)
    batch.set_rotor_efficiency([1.0, 0.5, 1.0, 1.0])  # (4,) applies to every vehicle
    np.testing.assert_array_equal(batch.rotor_efficiency[:, 1], 0.5)
    batch.set_max_rotor_speed(900.0)
    np.testing.assert_array_equal(batch.max_rotor_speed, 900.0)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        batch.set_max_rotor_speed([1.0, 2.0])
    with pytest.raises(ValueError, match=r"\(3, 4\)"):
        batch.set_rotor_efficiency(np.ones((2, 4)))

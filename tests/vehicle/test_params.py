"""QuadrotorParams and presets: validation, YAML round trip, derived quantities."""

import dataclasses
import math

import numpy as np
import pytest

import cufund
from cufund import presets


@pytest.mark.parametrize("make", [presets.crazyflie, presets.iris, presets.cu_astro])
def test_presets_are_valid_and_hover_below_max_speed(make):
    p = make()
    assert isinstance(p, cufund.QuadrotorParams)
    w_h = p.hover_rotor_speed
    assert 4 * p.k_f * w_h**2 == pytest.approx(p.mass * p.gravity, rel=1e-14)
    assert w_h < p.rotor_speed_max


def test_crazyflie_matches_rotorpy_numbers():
    from rotorpy.vehicles.crazyflie_params import quad_params as q

    p = presets.crazyflie()
    assert p.mass == q["mass"]
    assert p.inertia_matrix.tolist() == [
        [q["Ixx"], q["Ixy"], q["Ixz"]],
        [q["Ixy"], q["Iyy"], q["Iyz"]],
        [q["Ixz"], q["Iyz"], q["Izz"]],
    ]
    assert p.k_f == q["k_eta"]
    assert p.c_m * p.k_f == pytest.approx(q["k_m"], rel=1e-15)
    assert (p.tau_m, p.rotor_speed_min, p.rotor_speed_max) == (q["tau_m"], q["rotor_speed_min"], q["rotor_speed_max"])
    assert (p.rotor_drag_xy, p.rotor_drag_z) == (q["k_d"], q["k_z"])
    assert p.body_drag == (q["c_Dx"], q["c_Dy"], q["c_Dz"])
    # Same rotor centres, in PX4 order: RotorPy's r1..r4 are our rotors 3, 1, 4, 2.
    ours = p.rotor_positions()
    theirs = np.array([q["rotor_pos"][k] for k in ("r1", "r2", "r3", "r4")])
    np.testing.assert_allclose(ours[[2, 0, 3, 1]], theirs, atol=1e-15)
    # RotorPy's yaw torque k_m w^2 * dir equals our -spin * c_m * f.
    np.testing.assert_array_equal(-p.rotor_spins()[[2, 0, 3, 1]], q["rotor_directions"])


def test_cu_astro_fits_the_papers_footprint():
    p = presets.cu_astro()
    half_span = p.arm_length / math.sqrt(2) + 0.038  # motor offset + 3-inch propeller radius
    assert 2 * half_span == pytest.approx(0.216, abs=1e-3)


def test_allocation_matrix_round_trip(crazyflie):
    a, a_inv = crazyflie.allocation_matrix(), crazyflie.allocation_matrix_inverse()
    np.testing.assert_allclose(a @ a_inv, np.eye(4), atol=1e-12)
    assert a.shape == (4, 4)


def test_yaml_round_trip(tmp_path, crazyflie):
    import yaml

    path = tmp_path / "cf.yaml"
    path.write_text(yaml.safe_dump(crazyflie.to_dict()))
    assert cufund.QuadrotorParams.from_yaml(path) == crazyflie


def test_yaml_accepts_diagonal_inertia(tmp_path):
    path = tmp_path / "q.yaml"
    path.write_text(
        "mass: 1.0\ninertia: [0.01, 0.01, 0.02]\narm_length: 0.2\nk_f: 1.0e-5\nc_m: 0.02\n"
        "tau_m: 0.02\nrotor_speed_max: 1200\n"
    )
    p = cufund.QuadrotorParams.from_yaml(path)
    np.testing.assert_array_equal(p.inertia_matrix, np.diag([0.01, 0.01, 0.02]))


def test_unknown_yaml_key_is_named(tmp_path):
    path = tmp_path / "q.yaml"
    path.write_text(
        "mass: 1.0\ninertia: [0.01, 0.01, 0.02]\narm_length: 0.2\nk_f: 1.0e-5\nc_m: 0.02\n"
        "tau_m: 0.02\nrotor_speed_max: 1200\nmotor_constant: 3\n"
    )
    with pytest.raises(ValueError, match="unknown key 'motor_constant' in QuadrotorParams"):
        cufund.QuadrotorParams.from_yaml(path)


BAD_PARAMS = [
    ({"mass": 0.0}, "mass must be a finite number > 0"),
    ({"mass": -1.0}, "mass must be a finite number > 0"),
    ({"mass": float("nan")}, "mass must be a finite number > 0"),
    ({"mass": "heavy"}, "mass must be a real number"),
    ({"inertia": [[1e-5, 1e-6, 0], [0, 1e-5, 0], [0, 0, 2e-5]]}, "inertia must be symmetric"),
    ({"inertia": [1e-5, -1e-5, 2e-5]}, "inertia must be positive definite"),
    ({"inertia": [[1, 2], [3, 4]]}, "inertia must be a 3x3 matrix"),
    ({"inertia": [1e-5, float("inf"), 2e-5]}, "inertia must be a finite"),
    ({"arm_length": 0.0}, "arm_length must be a finite number > 0"),
    ({"k_f": -1e-8}, "k_f must be a finite number > 0"),
    ({"tau_m": 0.0}, "tau_m must be a finite number > 0"),
    ({"rotor_speed_max": -5.0}, "rotor_speed_max must be a finite number > rotor_speed_min"),
    ({"rotor_drag_xy": -1.0}, "rotor_drag_xy must be a finite number >= 0"),
    ({"body_drag": (0.0, -0.1, 0.0)}, "body_drag must be finite numbers >= 0"),
    ({"body_drag": (0.0, 0.1)}, "body_drag must be 3 real numbers"),
    ({"layout": "hex"}, "layout must be one of 'x', '\\+'"),
    ({"max_integration_step": 0.0}, "max_integration_step must be a finite number > 0"),
    ({"ground_plane": "yes"}, "ground_plane must be true or false"),
]


@pytest.mark.parametrize(("change", "message"), BAD_PARAMS)
def test_non_physical_parameters_raise_naming_the_field(crazyflie, change, message):
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(crazyflie, **change)


def test_params_are_frozen(crazyflie):
    with pytest.raises(dataclasses.FrozenInstanceError):
        crazyflie.mass = 2.0  # type: ignore[misc]


def test_missing_yaml_key_is_named(tmp_path):
    path = tmp_path / "q.yaml"
    path.write_text(
        "mass: 1.0\ninertia: [0.01, 0.01, 0.02]\narm_length: 0.2\nc_m: 0.02\ntau_m: 0.02\nrotor_speed_max: 1200\n"
    )
    with pytest.raises(cufund.ConfigError, match="missing key 'k_f' in QuadrotorParams"):
        cufund.QuadrotorParams.from_yaml(path)

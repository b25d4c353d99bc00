"""Ground and ceiling effect: hover equilibrium near a surface against the closed-form thrust ratios
(Cheeseman-Bennett with Sanchez-Cuevas et al.'s multirotor terms; the ceiling fit), per-rotor heights, the world's
floor and ceiling, and configuration errors."""

import dataclasses
import itertools

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.missions.tunnel_course import paper_tunnel_course
from cufund.vehicle import Quadrotor, presets
from cufund.vehicle.ground_effect import GroundEffectConfig
from cufund.worlds.surfaces import SurfaceProbe


def _ratio_ground(z, R, d, b, kb):
    """T_IGE / T_OGE, written out from the papers."""
    return 1.0 / (
        1.0
        - (R / (4 * z)) ** 2
        - R**2 * z / np.sqrt((d**2 + 4 * z**2) ** 3)
        - 0.5 * R**2 * z / np.sqrt((2 * d**2 + 4 * z**2) ** 3)
        - 2 * R**2 * z * kb / np.sqrt((b**2 + 4 * z**2) ** 3)
    )


def _ratio_ceiling(z, R, k1, k2):
    return 1.0 / (1.0 - (R / (z + k2)) ** 2 / k1)


@pytest.fixture
def params():
    return dataclasses.replace(presets.cu_astro(), ground_plane=False)


def _geometry(params):
    r = params.rotor_positions()
    d = min(np.linalg.norm(r[i] - r[j]) for i, j in itertools.combinations(range(4), 2))
    return 0.385 * params.arm_length, d, params.arm_length


def _hover_drift(params, cfg, z, omega, surfaces=(0.0, np.inf), seconds=0.5):
    cfg = cfg if cfg is None else dataclasses.replace(cfg, rotor_plane_height_m=0.0)  # hubs at the origin
    quad = Quadrotor(params)
    quad.set_ground_effect(cfg)
    quad.set_surfaces_z(surfaces)
    quad.hover((0.0, 0.0, z))
    quad.state.rotor_speeds[:] = omega
    for _ in range(int(seconds / 1e-3)):
        quad.step(1e-3, np.full(4, omega))
    return quad.state.p[2] - z, quad


@pytest.mark.parametrize("z", [0.04, 0.06, 0.1, 0.2, 0.5])
def test_hover_speed_near_the_ground_falls_by_the_predicted_factor(params, z):
    """Rotors at omega_OGE / sqrt(ratio(z)) hold the vehicle at z (thrust = weight); at omega_OGE it climbs."""
    R, d, b = _geometry(params)
    ratio = _ratio_ground(z, R, d, b, 2.0)
    assert ratio > 1.0
    omega = params.hover_rotor_speed / np.sqrt(ratio)
    drift, quad = _hover_drift(params, GroundEffectConfig(), z, omega)
    assert abs(drift) < 1e-6
    assert quad.accel_W[2] == pytest.approx(0.0, abs=1e-6)
    _, quad = _hover_drift(params, GroundEffectConfig(), z, params.hover_rotor_speed, seconds=1e-3)
    assert quad.accel_W[2] == pytest.approx(params.gravity * (ratio - 1.0), rel=1e-3)


@pytest.mark.parametrize("z", [0.03, 0.08, 0.3])
def test_single_rotor_form_is_cheeseman_bennett(params, z):
    R, *_ = _geometry(params)
    cfg = GroundEffectConfig(k_body=0.0, min_height_m=0.5 * R)
    _, quad = _hover_drift(params, cfg, z, params.hover_rotor_speed, seconds=1e-3)
    multi = _ratio_ground(z, R, _geometry(params)[1], 0.0, 0.0)
    assert quad.accel_W[2] == pytest.approx(params.gravity * (multi - 1.0), rel=1e-3)
    cb = 1.0 / (1.0 - (R / (4 * z)) ** 2)
    assert multi >= cb  # the neighbouring rotors only add


@pytest.mark.parametrize("gap", [0.04, 0.1, 0.3])
def test_ceiling_raises_thrust_by_the_fit(params, gap):
    R, *_ = _geometry(params)
    cfg = GroundEffectConfig(ceiling_k2_m=0.01)
    z = 1.0
    ratio = _ratio_ceiling(gap, R, 6.924, 0.01) * _ratio_ground(z, R, *_geometry(params)[1:], 2.0)
    omega = params.hover_rotor_speed / np.sqrt(ratio)
    drift, _ = _hover_drift(params, cfg, z, omega, surfaces=(0.0, z + gap))
    assert abs(drift) < 1e-6


def test_heights_are_clamped_and_far_surfaces_change_nothing(params):
    R, d, b = _geometry(params)
    _, low = _hover_drift(params, GroundEffectConfig(), 0.001, params.hover_rotor_speed, seconds=1e-3)
    assert low.accel_W[2] == pytest.approx(params.gravity * (_ratio_ground(R, R, d, b, 2.0) - 1.0), rel=1e-3)
    _, far = _hover_drift(params, GroundEffectConfig(), 5.0, params.hover_rotor_speed, surfaces=(-np.inf, np.inf))
    _, off = _hover_drift(params, None, 5.0, params.hover_rotor_speed)
    np.testing.assert_allclose(far.state.p, off.state.p, atol=1e-12)


def test_a_tilted_vehicle_sees_each_rotor_at_its_own_height(params):
    """Rolled near the ground, the low rotors gain more thrust: a roll moment pushes the low side up."""
    quad = Quadrotor(params)
    quad.set_ground_effect(GroundEffectConfig())
    quad.set_surfaces_z((0.0, np.inf))
    quad.hover((0.0, 0.0, 0.06))
    roll = np.radians(10.0)
    quad.state.q[:] = (np.cos(roll / 2), np.sin(roll / 2), 0.0, 0.0)  # left side (+y) up
    quad.step(1e-6, np.full(4, params.hover_rotor_speed))
    assert quad.alpha_B[0] < -1.0  # the right side (low) is pushed up: negative roll acceleration


def test_rotor_plane_height_lifts_the_hubs(params):
    R, d, b = _geometry(params)
    quad = Quadrotor(params)
    quad.set_ground_effect(GroundEffectConfig(rotor_plane_height_m=0.05))
    quad.set_surfaces_z((0.0, np.inf))
    quad.hover((0.0, 0.0, 0.02))
    quad.step(1e-9, np.full(4, params.hover_rotor_speed))
    assert quad.accel_W[2] == pytest.approx(params.gravity * (_ratio_ground(0.07, R, d, b, 2.0) - 1.0), rel=1e-3)


def test_world_floor_and_ceiling_of_the_tunnel_course():
    course = paper_tunnel_course()
    probe = SurfaceProbe(course.world)
    p = np.array([[-2.5, 0.0, 1.0], [-2.5, 0.0, 0.0], [-2.0, 1.0, 3.5]])
    s = probe(p)
    np.testing.assert_allclose(s[:, 0], 0.0, atol=1e-5)
    np.testing.assert_allclose(s[:, 1], 4.0, atol=1e-5)  # the arena's 4 m height
    f = course.frames[0]
    over_bar = np.array([[f.centre_W[0], f.centre_W[1], f.centre_W[2] + f.height / 2 + 0.15]])  # above the top bar
    np.testing.assert_allclose(probe(over_bar)[0], [0.0, 4.0], atol=1e-5)  # a bar is no floor (labels)
    every = SurfaceProbe(course.world, labels=None)(over_bar)[0]
    assert 0.05 < every[0] < over_bar[0, 2]  # with every object: the bar
    empty = SurfaceProbe(None, ground_plane=True)(p)
    np.testing.assert_array_equal(empty, [[0.0, np.inf]] * 3)
    assert SurfaceProbe(None, ground_plane=False)(p)[0, 0] == -np.inf


def test_a_plant_probing_a_world_pickles_and_continues_bit_for_bit():
    """The surface probe's ray-cast scene is rebuilt from its meshes: a pickled plant flies on like the original."""
    import pickle

    from cufund.worlds.surfaces import apply_ground_effect

    params = presets.cu_astro()
    quad = Quadrotor(params)
    apply_ground_effect(quad, GroundEffectConfig(), paper_tunnel_course().world)
    quad.hover((-2.5, 0.0, 0.08))
    copy = pickle.loads(pickle.dumps(quad))
    for q in (quad, copy):
        for _ in range(200):
            q.step(1e-3, np.full(4, params.hover_rotor_speed))
    np.testing.assert_array_equal(copy.state.as_vector(), quad.state.as_vector())
    np.testing.assert_array_equal(copy.surfaces_z, quad.surfaces_z)
    assert quad.surfaces_z[1] == pytest.approx(4.0, abs=1e-5)  # the probe ran: the arena's ceiling


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ({"rotor_radius_m": -0.1}, "rotor_radius_m"),
        ({"k_body": "lots"}, "k_body"),
        ({"ceiling_k1": 0}, "ceiling_k1"),
        ({"radius": 0.1}, "unknown key 'radius' in ground_effect"),
        ("yes", "ground_effect must be true, false or a mapping"),
    ],
)
def test_bad_ground_effect_is_refused_naming_the_field(value, match):
    with pytest.raises(ConfigError, match=match):
        GroundEffectConfig.parse(value)


def test_past_the_singularity_is_refused(params):
    with pytest.raises(ConfigError, match="singularity"):
        GroundEffectConfig(min_height_m=0.005).to_core(params)

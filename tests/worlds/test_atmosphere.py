"""The atmosphere's mean wind, shear, 1-cosine gusts and wind grid against their closed forms and scipy; its
configuration's errors."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from cufund import _core
from cufund.core.config import ConfigError
from cufund.scenarios.schema import ScenarioConfig
from cufund.vehicle import Quadrotor, QuadrotorBatch, presets
from cufund.worlds.atmosphere import AtmosphereConfig
from cufund.worlds.wind_grid import load_wind_grid, save_wind_grid


def _held(cfg, heights, times, tmp_base=None):
    """Wind seen at each time by vehicles held at the given heights (rewritten before each step)."""
    params = dataclasses.replace(presets.cu_astro(), ground_plane=False)
    n = len(heights)
    batch = QuadrotorBatch(params, n)
    batch.set_atmosphere(cfg.to_core(0, tmp_base))
    out = []
    t_prev = 0.0
    for t in times:
        if t > t_prev:
            batch.step(t - t_prev, np.zeros((n, 4)), 1)
            t_prev = t
        batch.p[:, :2] = 0.0
        batch.p[:, 2] = heights
        batch.v[:] = 0.0
        batch.step(1e-6, np.zeros((n, 4)), 1)  # an update at t (the period has passed): wind for (t, heights)
        t_prev += 1e-6
        out.append(np.array(batch.wind_W))
    return np.array(out)


def test_gust_is_the_exact_one_minus_cosine():
    g = {"t_start": 0.2, "duration": 0.5, "amplitude_mps": 4.0, "direction_deg": 90.0}
    cfg = AtmosphereConfig(kind="calm", gusts=[g], update_hz=1000.0)
    quad = Quadrotor(dataclasses.replace(presets.cu_astro(), ground_plane=False))
    quad.set_atmosphere(cfg.to_core(0))
    seen, times = [], []
    for _ in range(1000):
        t = quad.t
        quad.step(1e-3, np.zeros(4))
        seen.append(quad.wind_W.copy())
        times.append(t)
    times = np.array(times)
    s = times - 0.2
    expect = np.where((s >= 0) & (s <= 0.5), 2.0 * (1 - np.cos(2 * np.pi * s / 0.5)), 0.0)
    seen = np.array(seen)
    np.testing.assert_allclose(seen[:, 1], expect, rtol=0, atol=1e-12)
    np.testing.assert_allclose(seen[:, 0], expect * math.cos(math.pi / 2), atol=1e-12)
    np.testing.assert_array_equal(seen[:, 2], 0.0)
    assert seen[:, 1].max() == pytest.approx(4.0, abs=1e-4)


@pytest.mark.parametrize(
    ("shear", "law"),
    [
        ("none", lambda h: 3.0 * np.ones_like(h)),
        ("log", lambda h: 3.0 * np.log(h / 0.0457) / np.log(6.096 / 0.0457)),
        ({"kind": "power", "exponent": 0.2}, lambda h: 3.0 * (h / 6.096) ** 0.2),
    ],
)
def test_mean_wind_follows_the_shear_law_along_its_direction(shear, law):
    heights = np.array([0.5, 1.0, 6.096, 20.0])
    cfg = AtmosphereConfig(kind="constant", wind_20ft_mps=3.0, direction_deg=30.0, shear=shear)
    w = _held(cfg, heights, [0.0])[0]
    speed = law(heights)
    np.testing.assert_allclose(w[:, 0], speed * math.cos(math.radians(30)), rtol=1e-12)
    np.testing.assert_allclose(w[:, 1], speed * math.sin(math.radians(30)), rtol=1e-12)
    np.testing.assert_array_equal(w[:, 2], 0.0)


def test_log_shear_is_calm_below_the_roughness_length():
    cfg = AtmosphereConfig(kind="constant", wind_20ft_mps=3.0, shear={"kind": "log", "z0_m": 0.1})
    np.testing.assert_array_equal(_held(cfg, np.array([0.05, 0.1]), [0.0])[0], 0.0)


def _grid(tmp_path, rng):
    x = np.array([-1.0, 0.0, 0.5, 2.0])
    y = np.array([0.0, 1.0, 3.0])
    z = np.array([0.0, 0.7, 1.0, 1.5, 4.0])
    wind = rng.normal(size=(4, 3, 5, 3))
    path = tmp_path / "wind.npz"
    save_wind_grid(path, x, y, z, wind)
    return path, (x, y, z), wind


def test_grid_interpolation_matches_scipy_and_clamps_outside(tmp_path):
    rng = np.random.default_rng(0)
    path, axes, wind = _grid(tmp_path, rng)
    grid = load_wind_grid(path)
    a = AtmosphereConfig(kind="calm", grid_file=str(path)).to_core(0)
    inside = np.column_stack([rng.uniform(-1, 2, 500), rng.uniform(0, 3, 500), rng.uniform(0, 4, 500)])
    inside = np.vstack([inside, np.array(np.meshgrid(*axes, indexing="ij")).reshape(3, -1).T])  # the nodes too
    ref = RegularGridInterpolator(axes, wind, method="linear")
    np.testing.assert_allclose(_core.dynamics.atmosphere_grid_wind(a, inside), ref(inside), atol=1e-12)
    outside = rng.uniform(-10, 10, (200, 3))
    clipped = np.column_stack([np.clip(outside[:, k], axes[k][0], axes[k][-1]) for k in range(3)])
    np.testing.assert_allclose(_core.dynamics.atmosphere_grid_wind(a, outside), ref(clipped), atol=1e-12)
    assert grid.wind.shape == (4, 3, 5, 3)


def test_grid_reaches_the_plant_relative_to_the_scenario_file(tmp_path):
    rng = np.random.default_rng(1)
    path, axes, wind = _grid(tmp_path, rng)
    cfg = AtmosphereConfig(kind="calm", grid_file=path.name)
    w = _held(cfg, np.array([0.7]), [0.0], tmp_base=tmp_path)[0, 0]
    np.testing.assert_allclose(w, RegularGridInterpolator(axes, wind)([0.0, 0.0, 0.7])[0], atol=1e-12)


@pytest.mark.parametrize(
    ("write", "match"),
    [
        (
            lambda p: np.savez(p, x=[0, 1], y=[0, 1], z=[0, 1], wind=np.array([object()] * 24).reshape(2, 2, 2, 3)),
            "not a readable .npz of plain arrays",
        ),
        (lambda p: np.savez(p, x=[0, 1], y=[0, 1], wind=np.zeros((2, 2, 2, 3))), "lacks array 'z'"),
        (lambda p: np.savez(p, x=[0, 1], y=[0, 1], z=[0, 1], wind=np.zeros((2, 2, 3, 3))), "shape"),
        (lambda p: np.savez(p, x=[1, 0], y=[0, 1], z=[0, 1], wind=np.zeros((2, 2, 2, 3))), "strictly increasing"),
        (lambda p: np.savez(p, x=[0, 1], y=[0, 1], z=[0, 1], wind=np.full((2, 2, 2, 3), np.nan)), "finite"),
        (lambda p: p.write_bytes(b"PK\x03\x04 this is not a zip"), "not a readable .npz"),
        (lambda p: np.save(p, np.zeros(3)), "single array|not a readable"),
        (lambda p: None, "no such file"),
    ],
)
def test_hostile_grid_files_get_a_clear_error(tmp_path, write, match):
    path = tmp_path / "bad.npz"
    write(path)
    if path.with_suffix(".npz.npy").exists():
        path.with_suffix(".npz.npy").rename(path)
    with pytest.raises(ConfigError, match=match):
        load_wind_grid(path)


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ({"kind": "gale"}, "atmosphere.kind must be one of calm, constant, dryden"),
        ({"kind": "calm", "wind_20ft_mps": 3}, "needs kind constant or dryden"),
        ({"kind": "dryden", "wind_20ft_mps": -1}, "wind_20ft_mps must be a finite number >= 0"),
        ({"kind": "dryden", "wind_20ft_mps": 101}, r"wind_20ft_mps must be in \[0, 100\]"),
        ({"kind": "dryden", "speed": 3}, "unknown key 'speed' in atmosphere"),
        ({"kind": "dryden", "shear": "cubic"}, "shear.kind must be one of none, log, power"),
        ({"kind": "calm", "gusts": [{"t_start": 1, "duration": 0, "amplitude_mps": 1}]}, "duration"),
        ({"kind": "calm", "gusts": [{"t_start": 1, "duration": 1}]}, "missing key 'amplitude_mps'"),
        ({"kind": "dryden", "seed": -1}, "atmosphere.seed"),
        ({"kind": "dryden", "update_hz": 0.5}, "update_hz"),
    ],
)
def test_bad_atmosphere_is_refused_naming_the_field(value, match):
    with pytest.raises(ConfigError, match=match):
        ScenarioConfig.from_dict({"atmosphere": value})


def test_scenario_keys_round_trip_and_default_off():
    assert ScenarioConfig().atmosphere is None and ScenarioConfig().ground_effect is None
    cfg = ScenarioConfig.from_dict({"atmosphere": "calm", "ground_effect": True})
    assert cfg.atmosphere == AtmosphereConfig() and cfg.ground_effect is not None
    cfg = ScenarioConfig().with_overrides(
        [
            "atmosphere.kind=dryden",
            "atmosphere.wind_20ft_mps=3",
            "atmosphere.gusts=[{t_start: 2, duration: 1, amplitude_mps: 2}]",
        ]
    )
    assert cfg.atmosphere.wind_20ft_mps == 3.0 and cfg.atmosphere.gusts[0].amplitude_mps == 2.0
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg


def test_pickled_plant_keeps_its_atmosphere_and_ground_effect():
    import pickle

    from cufund.vehicle.ground_effect import GroundEffectConfig

    params = presets.cu_astro()
    quad = Quadrotor(params, wind=lambda t, p: np.zeros(3))
    quad.set_atmosphere(AtmosphereConfig(kind="dryden", wind_20ft_mps=4.0, seed=9).to_core(0))
    assert quad.fast_step is not None  # the atmosphere replaced the wind function
    quad.set_ground_effect(GroundEffectConfig())
    copy = pickle.loads(pickle.dumps(quad))
    fresh = Quadrotor(params)
    fresh.set_atmosphere(AtmosphereConfig(kind="dryden", wind_20ft_mps=4.0, seed=9).to_core(0))
    fresh.set_ground_effect(GroundEffectConfig())
    for q in (copy, fresh):
        q.hover((0.0, 0.0, 0.1))
        for _ in range(50):
            q.step(1e-3, np.full(4, params.hover_rotor_speed))
    np.testing.assert_array_equal(copy.state.as_vector(), fresh.state.as_vector())
    assert np.linalg.norm(copy.wind_W) > 0.0

"""The plant's Dryden turbulence against the MIL-F-8785C low-altitude model: its PSDs (Welch) within 10 % over a
decade, its intensity per axis, its scales from the standard's formulas, and seeded repeatability."""

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from cufund.vehicle import QuadrotorBatch, presets
from cufund.worlds.atmosphere import AtmosphereConfig
from cufund.worlds.dryden import dryden_psd, dryden_scales

FT = 0.3048


def _model_scales(h_m, w20):
    """The standard's low-altitude forms, written out here (h in feet, clamped to [10, 1000] ft)."""
    h = min(max(h_m / FT, 10.0), 1000.0)
    s = 0.177 + 0.000823 * h
    sw = 0.1 * w20
    return {
        "sigma_u": sw / s**0.4,
        "sigma_v": sw / s**0.4,
        "sigma_w": sw,
        "L_u": h / s**1.2 * FT,
        "L_v": h / s**1.2 * FT,
        "L_w": h * FT,
    }


@pytest.mark.parametrize("h_m", [0.5, 3.048, 10.0, 100.0, 304.8, 1000.0])
def test_scales_follow_the_standard(h_m):
    got = dryden_scales(h_m, 7.0)
    for k, v in _model_scales(h_m, 7.0).items():
        assert got[k] == pytest.approx(v, rel=1e-12), k


def _sample(n_vehicles=48, steps=12000, h=3.0, w20=3.0, V=20.0, seed=5, rate=50.0):
    """Wind seen by vehicles held at height h (state rewritten before each step), airspeed floored at V."""
    params = dataclasses.replace(presets.cu_astro(), max_integration_step=1.0 / rate, ground_plane=False)
    batch = QuadrotorBatch(params, n_vehicles)
    cfg = AtmosphereConfig(
        kind="dryden", wind_20ft_mps=w20, shear="none", seed=seed, update_hz=rate, min_airspeed_mps=V
    )
    batch.set_atmosphere(cfg.to_core(0))
    cmd = np.zeros((n_vehicles, 4))
    out = np.empty((steps, n_vehicles, 3))
    for k in range(steps):
        batch.p[:] = (0.0, 0.0, h)
        batch.v[:] = 0.0
        batch.q[:] = (1.0, 0.0, 0.0, 0.0)
        batch.w[:] = 0.0
        batch.step(1.0 / rate, cmd, 1)
        out[k] = batch.wind_W
    return out


@pytest.fixture(scope="module")
def sample():
    return _sample()


def test_sigma_per_axis_matches_the_model(sample):
    s = _model_scales(3.0, 3.0)
    turb = sample - np.array([3.0, 0.0, 0.0])  # the mean wind along +x (shear none)
    std = turb.reshape(-1, 3).std(axis=0)
    np.testing.assert_allclose(std, [s["sigma_u"], s["sigma_v"], s["sigma_w"]], rtol=0.05)
    np.testing.assert_allclose(turb.reshape(-1, 3).mean(axis=0), 0.0, atol=0.05 * s["sigma_u"])


@pytest.mark.parametrize(("axis", "col", "band"), [("u", 0, (0.1, 1.0)), ("v", 1, (0.1, 1.0)), ("w", 2, (0.5, 5.0))])
def test_psd_matches_the_model_over_a_decade(sample, axis, col, band):
    rate, V = 50.0, 20.0
    s = _model_scales(3.0, 3.0)
    x = sample[:, :, col] - (3.0 if col == 0 else 0.0)
    f, P = signal.welch(x, fs=rate, nperseg=4096, axis=0)
    P = P.mean(axis=1)
    model = 2 * np.pi * dryden_psd(axis, 2 * np.pi * f, s[f"sigma_{axis}"], s[f"L_{axis}"], V)  # per Hz
    edges = np.geomspace(band[0], band[1], 6)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (f >= lo) & (f < hi)
        assert sel.sum() >= 3
        ratio = P[sel].mean() / model[sel].mean()
        assert abs(ratio - 1.0) < 0.10, (axis, lo, hi, ratio)


def test_model_psd_integrates_to_sigma_squared():
    w = np.linspace(0.0, 2e4, 2_000_001)
    for axis in "uvw":
        assert np.trapezoid(dryden_psd(axis, w, 0.7, 12.0, 5.0), w) == pytest.approx(0.49, rel=1e-3)


def test_same_seed_is_bit_identical_and_another_differs():
    a = _sample(n_vehicles=2, steps=500, seed=11)
    b = _sample(n_vehicles=2, steps=500, seed=11)
    c = _sample(n_vehicles=2, steps=500, seed=12)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert not np.array_equal(a[:, 0], a[:, 1])  # each vehicle its own stream


def test_reset_restarts_the_turbulence_from_its_seed():
    params = dataclasses.replace(presets.cu_astro(), ground_plane=False)
    batch = QuadrotorBatch(params, 1)
    batch.set_atmosphere(AtmosphereConfig(kind="dryden", wind_20ft_mps=5.0, seed=3).to_core(0))

    def run():
        batch.hover(np.array([0.0, 0.0, 2.0]))
        winds = []
        for _ in range(100):
            batch.step(1e-3, np.full((1, 4), params.hover_rotor_speed), 1)
            winds.append(batch.wind_W[0].copy())
        return np.array(winds)

    first = run()
    batch.reset()
    np.testing.assert_array_equal(run(), first)
    assert math.isfinite(first.sum()) and np.ptp(first[:, 2]) > 0

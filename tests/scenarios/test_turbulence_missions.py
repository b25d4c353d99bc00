"""The square and the tunnel in moderate turbulence (Dryden, 20 ft wind 3 m/s, seeded) complete; the same seed
repeats a run bit for bit, another seed flies another gust history."""

import math

import pytest

from cufund.scenarios import load_scenario, run_scenario

MODERATE = ["atmosphere.kind=dryden", "atmosphere.wind_20ft_mps=3", "atmosphere.direction_deg=30"]
_TIMING = {"wall_time_s", "real_time_factor", "component_seconds"}


def _figures(m):
    return {k: v for k, v in m.items() if k not in _TIMING}


@pytest.fixture(scope="module")
def square_runs():
    base = load_scenario("square")
    return [run_scenario(base.with_overrides([*MODERATE, f"atmosphere.seed={s}"])) for s in (1, 1, 2)]


def test_square_completes_in_moderate_turbulence(square_runs):
    m = square_runs[0].metrics
    assert m["status"] == "completed"
    assert m["tracking_rmse_m"] <= 0.05
    assert m["tracking_max_m"] <= 0.15


def test_the_wind_reached_the_plant(square_runs):
    calm = run_scenario(load_scenario("square")).metrics
    assert _figures(calm)["tracking_rmse_m"] != square_runs[0].metrics["tracking_rmse_m"]


def test_same_seed_is_bit_identical_and_another_seed_differs(square_runs):
    a, b, c = (_figures(r.metrics) for r in square_runs)
    assert a == b
    assert a["tracking_rmse_m"] != c["tracking_rmse_m"]


def test_tunnel_completes_in_moderate_turbulence():
    m = run_scenario(load_scenario("tunnel").with_overrides([*MODERATE, "atmosphere.seed=1"])).metrics
    assert m["status"] == "completed"
    assert m["frames_passed"] == 5
    assert m["landed_beyond_last_frame"] is True
    assert math.isfinite(m["tracking_rmse_m"]) and m["tracking_rmse_m"] <= 0.1


def test_tunnel_completes_with_ground_effect():
    """The course's floor and ceiling (ground_effect: true): every frame passed, landed beyond the last one."""
    m = run_scenario(load_scenario("tunnel").with_overrides(["ground_effect=true"])).metrics
    assert m["status"] == "completed" and m["success"] is True, m["reason"]
    assert m["frames_passed"] == 5 and m["landed_beyond_last_frame"] is True
    assert m["tracking_rmse_m"] <= 0.05 and m["min_clearance_m"] > 0.15

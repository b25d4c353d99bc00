"""Scenario YAML validation: clear errors naming the field."""

import pytest

from cufund import ConfigError, ScenarioConfig, available_scenarios, load_scenario


def test_square_is_listed_and_loads():
    assert "square" in available_scenarios()
    cfg = load_scenario("square")
    assert cfg.vehicle == "cu_astro" and cfg.controller.kind == "pid" and cfg.rates.physics_hz == 1000.0
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg


@pytest.mark.parametrize("data, match", [
    ({"duraton": 3}, "unknown key 'duraton' in scenario"),
    ({"controller": {"kind": "lqr"}}, "controller.kind must be 'pid' or 'geometric'"),
    ({"controller": {"position": {"xy_pp": 1}}}, "unknown key 'xy_pp' in controller.position"),
    ({"controller": {"rate": {"roll_p": -1}}}, "RateControlParams.roll_p must be a finite number >= 0"),
    ({"rates": {"physics_hz": 0}}, "rates.physics_hz must be a finite number > 0"),
    ({"trajectory": {"waypoints": [[0, 0, 1]]}}, "trajectory.waypoints must be a list of at least 2"),
    ({"trajectory": {"waypoints": [[0, 0, 1], [1, 0, 0]]}}, "above 0.1 m"),
    ({"trajectory": {"v_max": 0}}, "trajectory.v_max must be a number > 0"),
    ({"vehicle": "bebop"}, "vehicle must be one of crazyflie, iris, cu_astro"),
    ({"vehicle": {"mass": 1.0}}, "vehicle: .*missing.*inertia"),
    ({"seed": -1}, "seed must be an integer >= 0"),
    ({"duration": "long"}, "duration must be a finite number > 0"),
    ({"duration": float("inf")}, "duration must be a finite number > 0"),
    ({"name": 5}, "name must be a non-empty string"),
    ({"trajectory": {"yaw": [float("nan")] * 5}}, "trajectory.yaw must have one finite angle per waypoint"),
])
def test_bad_scenarios(data, match):
    with pytest.raises(ConfigError, match=match):
        ScenarioConfig.from_dict(data)


def test_unknown_scenario_name(tmp_path):
    with pytest.raises(ConfigError, match="unknown scenario 'circle'; built-in: square"):
        load_scenario("circle")
    bad = tmp_path / "bad.yaml"
    bad.write_text("rates: {physics_hz: 1000, rate_hz: 300}\n")
    from cufund.scenario import run_scenario

    with pytest.raises(ValueError, match="must divide the physics rate"):
        run_scenario(load_scenario(bad))

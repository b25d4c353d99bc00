"""Deconfliction in a flown fleet (mission kind fleet): two vehicles sent head-on along one line (each to the row
beyond the other's home) collide without deconfliction and, with the start delays of time-shifting, keep the minimum
separation, measured by the fleet simulator on the true states."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.missions.deconfliction import min_separation
from cufund.missions.fleet_mission import plan_fleet_mission
from cufund.scenarios.fleet import build_fleet
from cufund.scenarios.schema import ScenarioConfig, load_scenario


def _head_on(min_sep: float) -> ScenarioConfig:
    data = load_scenario("fleet_survey").to_dict()
    data["name"] = "fleet_head_on"
    data["mission"].update(
        request="zigzag over the field with 2 rows of 1 waypoint at 3 m",  # row 1 at y = 2.5, row 2 at y = 7.5
        fields={"field": [[0, 0], [10, 0], [10, 10], [0, 10]]},
        homes={"uav1": [5, 12, 0], "uav2": [5, -2, 0]},  # uav1 flies south to row 1, uav2 north to row 2
        geofence=[[-5, -6], [15, -6], [15, 16], [-5, 16]],
        min_separation=min_sep,
    )
    data["vehicles"] = [{"name": "uav1", "start": {"p": [5, 12, 0]}}, {"name": "uav2", "start": {"p": [5, -2, 0]}}]
    return ScenarioConfig.from_dict(data)


def _plan(cfg: ScenarioConfig):
    """The plan each vehicle makes (with the scenario's commander parameters)."""
    return plan_fleet_mission(cfg.mission.params, cfg.planner.params)


def test_a_head_on_pair_collides_without_deconfliction():
    cfg = _head_on(0.0)  # 0: no deconfliction, both start at once
    assert _plan(cfg).delays == {"uav1": 0.0, "uav2": 0.0}
    run = build_fleet(cfg).run()
    assert run.status == "crashed" and run.metrics["fleet_collisions"] >= 1
    assert "uav1" in run.message and "uav2" in run.message


def test_a_head_on_pair_keeps_the_minimum_separation_with_deconfliction():
    cfg = _head_on(2.0)
    plan = _plan(cfg)
    assert plan.delays["uav1"] == 0.0 and plan.delays["uav2"] > 0.0  # the lower priority waits
    planned = min_separation(plan.trajectories["uav1"], plan.trajectories["uav2"].shifted(plan.delays["uav2"]))[0]
    assert planned >= 2.0
    run = build_fleet(cfg).run()
    assert run.status == "completed", run.message
    assert run.metrics["fleet_collisions"] == 0
    assert run.metrics["fleet_min_separation_m"] >= 2.0
    for name in ("uav1", "uav2"):
        assert run.metrics["vehicles"][name]["fleet_mission"]["completed"], name


def test_the_plan_models_the_commanders_flight():
    """The planned trajectory is what the vehicle flies: the same duration and, along the way, the true position
    within half a metre of the plan (the commander's reference, without the vehicle's tracking lag)."""
    cfg = _head_on(2.0)
    plan = _plan(cfg)
    run = build_fleet(cfg).run()
    for name, home in (("uav1", (5, 12, 0)), ("uav2", (5, -2, 0))):
        states = run.runs[name].result.states
        assert states["p_W"][-1] == pytest.approx(home, abs=0.3)
        moving = states["t"][(states["p_W"][:, 2] > 0.05)]
        flown = moving[-1] - moving[0]
        planned = plan.trajectories[name].t_end
        assert abs(flown - planned) < 1.5, (name, planned, flown)
        # the reference along the way: the true position at the planned times, within the tracking error
        t0 = cfg.mission.params.start_s + plan.delays[name]
        tt = np.arange(0.0, planned, 0.5)
        idx = np.searchsorted(states["t"], t0 + tt)
        err = np.linalg.norm(states["p_W"][idx] - plan.trajectories[name].at(tt), axis=1)
        assert err.max() < 0.5, (name, float(err.max()))

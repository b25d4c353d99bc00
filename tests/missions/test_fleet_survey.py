"""The fleet_survey scenario (mission kind fleet): three vehicles cover the 30 m x 20 m field from the one request in
the scenario, judged on their true flown tracks: every point of the field lies within half a lane spacing (plus the
tracking margin) of a track flown at the requested height, each vehicle stayed over its own cell, nobody came
closer than the minimum separation, all landed back home. Plus the kind's refusals."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.missions import MissionRequestError, parse_mission
from cufund.missions.fleet_context import FleetContext
from cufund.missions.fleet_mission import FleetMissionParams, plan_fleet_mission
from cufund.scenarios.fleet import build_fleet, vehicle_scenario
from cufund.scenarios.schema import ScenarioConfig, load_scenario


@pytest.fixture(scope="module")
def survey():
    cfg = load_scenario("fleet_survey")
    fleet = build_fleet(cfg)
    return cfg, fleet.run(), fleet


def test_three_vehicles_cover_the_field_from_one_request(survey):
    cfg, run, _ = survey
    assert run.status == "completed", run.message
    assert run.metrics["fleet_collisions"] == 0
    assert run.metrics["fleet_min_separation_m"] >= cfg.mission.params.min_separation
    altitude, half_lane = 4.0, 2.5  # "at 4 m, lanes 5 m apart"
    tracks = []
    for name in ("uav1", "uav2", "uav3"):
        states = run.runs[name].result.states
        p = states["p_W"]
        fm = run.metrics["vehicles"][name]["fleet_mission"]
        assert fm["mission"] == "survey" and fm["completed"], name
        high = p[np.abs(p[:, 2] - altitude) < 0.3]
        assert len(high) > 1000, name
        tracks.append(high[:, :2])
        home = np.asarray(cfg.mission.params.homes[name], dtype=float)
        assert np.linalg.norm(p[-1] - home) < 0.3, name  # back home, on the ground
    # each vehicle surveyed its own third of the field (the cells split it along x)
    spans = [(t[:, 0].min(), t[:, 0].max()) for t in tracks]
    assert spans[0][1] < spans[1][0] and spans[1][1] < spans[2][0]
    xs, ys = np.meshgrid(np.linspace(0, 30, 31), np.linspace(0, 20, 21))
    field = np.stack([xs.ravel(), ys.ravel()], axis=1)
    flown = np.concatenate(tracks)[::10]
    nearest = np.min(np.linalg.norm(field[:, None, :] - flown[None, :, :], axis=2), axis=1)
    assert nearest.max() <= half_lane + 0.5, field[np.argmax(nearest)]


def test_each_vehicle_plans_the_same_fleet_mission():
    cfg = load_scenario("fleet_survey")
    plans = [
        plan_fleet_mission(vehicle_scenario(cfg, n).mission.params, vehicle_scenario(cfg, n).planner.params)
        for n in ("uav1", "uav2", "uav3")
    ]
    for p in plans[1:]:
        assert p.delays == plans[0].delays
        assert all(np.array_equal(p.waypoints[n], plans[0].waypoints[n]) for n in p.waypoints)


def test_a_built_fleet_is_the_context_of_a_request(survey):
    """What a ground station on the fleet does: the request reads the scenario's field, fence and the homes."""
    cfg, _, fleet = survey
    ctx = FleetContext.of(fleet)
    assert ctx.names == ("uav1", "uav2", "uav3") and set(ctx.fields) == {"field"}
    assert ctx.geofence == tuple(tuple(map(float, p)) for p in cfg.mission.params.geofence)
    for name in ctx.names:
        np.testing.assert_allclose(ctx.home(name), cfg.mission.params.homes[name], atol=0.05)
    planned = plan_fleet_mission(cfg.mission.params, cfg.planner.params).waypoints
    asked = parse_mission(cfg.mission.params.request, fleet).waypoints(fleet)
    assert set(asked) == set(planned)
    for name in planned:
        np.testing.assert_allclose(asked[name], planned[name])
    with pytest.raises(MissionRequestError, match="outside the geofence"):
        parse_mission("orbit (40, 2) at radius 3 m", fleet)


def _params(**kw):
    base = dict(
        request="survey the field with all drones at 4 m",
        homes={"uav1": [0, -3, 0], "uav2": [10, -3, 0]},
        fields={"field": [[0, 0], [20, 0], [20, 10], [0, 10]]},
        geofence=[[-5, -5], [25, -5], [25, 15], [-5, 15]],
    )
    base.update(kw)
    return FleetMissionParams(**base)


def test_the_kind_refuses_what_it_cannot_fly():
    with pytest.raises(ConfigError, match="not one of the grammar's phrases"):
        plan_fleet_mission(_params(request="take nice pictures of the barn"))
    with pytest.raises(ConfigError, match="outside the geofence"):
        plan_fleet_mission(_params(request="orbit (30, 2) at radius 3 m"))
    with pytest.raises(ConfigError, match="mission.request"):
        _params(request="")
    with pytest.raises(ConfigError, match="geofence"):
        _params(geofence=[[0, 0], [1, 1]])
    data = load_scenario("fleet_survey").to_dict()
    data["mission"]["homes"]["uav2"] = [16, -3, 0]
    with pytest.raises(ConfigError, match="must be the vehicle's start"):
        build_fleet(ScenarioConfig.from_dict(data))

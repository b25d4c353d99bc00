"""A formation flown by a fleet (mission kind fleet, "fly in a line formation ..."): the three vehicles assemble at
the path's start (the early ones wait), then fly the leg in step: on the true states the line keeps its shape, each
neighbour 3 m to the side and level with the next, all the way along; then they return home apart."""

from __future__ import annotations

import numpy as np

from cufund.missions.fleet_mission import plan_fleet_mission
from cufund.scenarios.fleet import build_fleet
from cufund.scenarios.schema import ScenarioConfig, load_scenario

HOMES = {"uav1": [-4, 8, 0], "uav2": [-2, 5, 0], "uav3": [-6, 2, 0]}


def _formation() -> ScenarioConfig:
    data = load_scenario("fleet_survey").to_dict()
    data["name"] = "fleet_formation"
    data["mission"].update(
        request="fly in a line formation through (0, 5) and (24, 5) at 3 m, 3 m apart",
        homes=HOMES,
        geofence=[[-10, -5], [30, -5], [30, 15], [-10, 15]],
    )
    data["vehicles"] = [{"name": n, "start": {"p": p}} for n, p in HOMES.items()]
    return ScenarioConfig.from_dict(data)


def test_a_line_formation_flies_in_step():
    cfg = _formation()
    plan = plan_fleet_mission(cfg.mission.params, cfg.planner.params)
    assert plan.mission.kind == "formation" and set(plan.delays.values()) == {0.0}
    # line abreast heading east: uav1 on the left (north), uav2 in the middle, uav3 on the right
    np.testing.assert_allclose([plan.waypoints[n][0] for n in HOMES], [[0, 8, 3], [0, 5, 3], [0, 2, 3]], atol=1e-9)
    run = build_fleet(cfg).run()
    assert run.status == "completed", run.message
    assert run.metrics["fleet_collisions"] == 0 and run.metrics["fleet_min_separation_m"] >= 2.0
    states = {n: run.runs[n].result.states for n in HOMES}
    t = states["uav1"]["t"]
    n = min(len(s["t"]) for s in states.values())
    p = {k: s["p_W"][:n] for k, s in states.items()}
    # the leg: every vehicle between x = 2 and 22 at once
    leg = np.all([(p[k][:, 0] > 2) & (p[k][:, 0] < 22) for k in HOMES], axis=0)
    assert leg.sum() > 5000  # > 5 s of the 1 kHz states
    for a, b in (("uav1", "uav2"), ("uav2", "uav3")):
        d = p[a][leg] - p[b][leg]
        assert np.abs(d[:, 0]).max() < 0.1, (a, b, np.abs(d[:, 0]).max())  # level: in step along the leg
        assert np.abs(d[:, 1] - 3.0).max() < 0.1, (a, b)  # 3 m apart across it
    assert np.abs(p["uav2"][leg][:, 2] - 3.0).max() < 0.3
    for k, home in HOMES.items():
        np.testing.assert_allclose(states[k]["p_W"][-1], home, atol=0.3)
    assert t[-1] > 0

"""The forest scenario: the local planner on the growing ESDF map of a Mid-360, placed with LiDAR-inertial
odometry (no ground truth in the loop), crosses seeded forests to the goal and lands there, never closer than
its radius to a trunk. The clearance is re-measured here by Open3D's
exact distance to the trunks' triangles (independent of both the ESDF and the metric's cylinder model).

A 12 m goal in a 24 m forest square of the scenario's density keeps the test short; the scenario itself flies
30 m (`cufund run forest --set world.seed=K`)."""

from __future__ import annotations

import numpy as np
import pytest

from cufund import load_scenario
from cufund.scenarios.build import run_scenario

open3d = pytest.importorskip("open3d")

GOAL = [12.0, 0.0, 1.5]


def _short_forest(seed: int):
    cfg = load_scenario("forest")
    density = cfg.world.params.n_trees / cfg.world.params.size**2
    assert density >= 0.15  # the scenario's density, kept below
    return cfg.with_overrides(
        {
            "world.seed": seed,
            "world.size": 24.0,
            "world.n_trees": int(np.ceil(density * 24**2)),
            "planner.goal": GOAL,
            "mapper.size": [18.0, 12.0, 4.0],
            "mapper.origin_W": [-3.0, -6.0, -0.5],
            "duration": 30.0,
        }
    )


def _trunk_distance(world, p):
    scene = open3d.t.geometry.RaycastingScene()
    for obj in world.objects:
        if obj.label == "tree":
            scene.add_triangles(
                open3d.core.Tensor(obj.vertices.astype(np.float32)), open3d.core.Tensor(obj.triangles.astype(np.uint32))
            )
    return scene.compute_distance(open3d.core.Tensor(p.astype(np.float32))).numpy()


@pytest.mark.parametrize("seed", [1, 3])  # layouts whose straight line to the goal hits a trunk
def test_forest_flight_reaches_the_goal_clear_of_the_trunks(seed):
    from cufund.scenarios.build import build_simulation

    cfg = _short_forest(seed)
    assert cfg.estimator is not None and cfg.estimator.kind == "lio"  # the map and the controller use the LIO
    world = build_simulation(cfg).context.world
    run = run_scenario(cfg)
    m = run.metrics
    assert m["status"] == "completed", m  # ended by landing, not by the duration or a collision
    assert m["success"] and m["goal_reached"], m
    p = run.result.states["p_W"]
    assert np.linalg.norm(p[-1] - [GOAL[0], GOAL[1], 0.0]) < 0.1  # landed at the goal
    d = _trunk_distance(world, p)
    radius = m["clearance_radius_m"]
    assert d.min() >= radius
    assert m["min_clearance_m"] <= d.min() + 1e-3  # the metric's cylinders never overstate the clearance
    # the straight line to the goal is blocked in these layouts: the planner had to weave
    line = np.linspace([0.0, 0.0, 1.5], GOAL, 500)
    assert _trunk_distance(world, line).min() < radius
    assert m["path_length_m"] > 12.0 and m["plan_ms_median"] is not None and m["replans"] > 50
    assert m["plan_cpu_ms_median"] is not None
    assert m["odometry_rmse_m"] < 0.1 and m["lio_scans"] > 50  # flown on the estimate (truth re-measured here)

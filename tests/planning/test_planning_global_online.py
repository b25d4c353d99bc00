"""The ``global`` planner kind on the map built online: the obstacles exist only in the map a mapper publishes
(no world at all), so a plan that avoids them can only have come from that map; the flight is measured by the
true states' distance to the obstacle boxes themselves. A pillar appearing across the flown min-snap makes it
brake and replan; a goal walled off on the map makes it hover and land with a message; building it never reads
the world."""

from __future__ import annotations

import numpy as np

from cufund import ScenarioConfig, load_scenario
from cufund.planning.global_planner_component import GlobalPlannerComponent
from cufund.scenarios import build as build_module
from cufund.scenarios.build import build_simulation, run_built
from planning_support import GAINS, PILLAR, ScriptedMap, UpdateLog

GOAL = np.array([8.0, 0.0, 1.5])
WALL = (np.array([4.0, -3.0, 0.0]), np.array([4.3, 3.0, 3.0]))  # across the whole mapped box


def _config(**planner):
    return ScenarioConfig.from_dict(
        {
            "name": "global_online_test",
            "vehicle": "cu_astro",
            "start_p_W": [0.0, 0.0, 0.0],
            "duration": 30.0,
            "planner": {"kind": "global", "goal": GOAL.tolist(), "v_max": 1.5, **planner},
            "controller": {"kind": "pid", **GAINS},
            "rates": {"physics_hz": 1000, "trajectory_hz": 250, "position_hz": 250, "attitude_hz": 250, "rate_hz": 500},
        }
    )


def _fly(box, t_appear, **planner):
    probe = UpdateLog()
    built = build_simulation(_config(**planner), extra_components=(ScriptedMap(box, t_appear), probe))
    assert built.context.world is None  # nothing to read but the map
    run = run_built(built)
    planner_c = next(c for c in built.simulator.components if isinstance(c, GlobalPlannerComponent))
    return run, planner_c, probe


def _box_distance(p, lo, hi):
    return np.linalg.norm(np.maximum(np.maximum(lo - p, 0.0), p - hi), axis=1)


def _landed_at_goal(run):
    p = run.result.states["p_W"]
    assert np.linalg.norm(p[-1, :2] - GOAL[:2]) < 0.1 and p[-1, 2] < 0.05


def test_plans_round_an_obstacle_only_the_online_map_holds():
    run, planner, probe = _fly(PILLAR, t_appear=0.0)
    m = run.metrics
    assert m["status"] == "completed" and m["success"] and m["global_status"] == "ok", m
    assert m["replans"] == 1 and m["replan_status"] == {"ok": 1} and m["global_abort"] is None
    # the straight line runs through the pillar; the flight (true states) keeps the radius from the box itself
    assert _box_distance(np.linspace([0, 0, 1.5], GOAL, 200), *PILLAR).min() == 0.0
    assert _box_distance(run.result.states["p_W"], *PILLAR).min() >= planner.params.radius - 0.05
    _landed_at_goal(run)
    # the keys of the known-map planner, for the first plan
    assert m["global_path_vertices"] >= 3 and m["global_min_map_clearance_m"] >= planner.params.radius
    assert m["global_peak_speed_mps"] <= 1.5 * 1.01 and m["global_plan_ms"] > 0


def test_brakes_and_replans_when_a_new_obstacle_blocks_the_plan():
    run, planner, probe = _fly(PILLAR, t_appear=6.0)
    m = run.metrics
    assert m["status"] == "completed" and m["success"], m
    assert m["replan_status"] == {"ok": 2, "blocked": 1}, m["replan_status"]
    # the min-snap flown when the pillar appeared ran straight through it ...
    first = probe.updates[0].trajectory
    assert probe.updates[0].t < 6.0
    ts = np.linspace(first.t_start, first.t_end, 400)
    assert _box_distance(first.sample(ts).p_W, *PILLAR).min() == 0.0
    # ... it braked (to rest, within the acceleration limit) and flew round: radius kept from the box
    brake = probe.updates[1].trajectory
    s = brake.sample(np.linspace(brake.t_start, brake.t_end, 200))
    assert np.linalg.norm(s.v_W[-1]) < 1e-9 and np.abs(s.a_W).max() <= planner.params.a_max + 1e-9
    assert _box_distance(run.result.states["p_W"], *PILLAR).min() >= planner.params.radius - 0.05
    _landed_at_goal(run)


def test_guide_is_replanned_when_a_new_obstacle_blocks_it():
    run, planner, probe = _fly(PILLAR, t_appear=6.0, local=True, replan_interval_s=30.0)
    m = run.metrics
    assert m["status"] == "completed" and m["success"], m
    assert m["global_replans"] >= 2 and set(m["global_replan_status"]) == {"ok"}
    assert _box_distance(planner._path, *PILLAR).min() >= planner.params.radius  # the guide now goes round
    assert _box_distance(run.result.states["p_W"], *PILLAR).min() >= planner.params.radius - 0.05


def test_an_unreachable_goal_hovers_then_lands_with_a_message():
    run, planner, _ = _fly(WALL, t_appear=0.0, give_up_s=3.0)
    m = run.metrics
    assert m["status"] == "completed" and not m["goal_reached"], m  # the run ended landed
    assert m["global_status"] == "no_path" and "no astar plan" in m["global_abort"] and "no_path" in m["global_abort"]
    assert m["replan_status"]["gave_up"] == 1
    p = run.result.states["p_W"]
    assert np.linalg.norm(p[-1, :2]) < 0.1 and p[-1, 2] < 0.05  # landed where it hovered, never near the wall
    assert p[:, 0].max() < 0.1


def test_global_never_reads_the_world_at_build_time(monkeypatch):
    """forest_global's planner part is built without a look at the world (the known-map kind does look)."""
    reads: list[str] = []
    cls = build_module.ScenarioBuildContext
    slot = cls.__dict__["world"]  # a slot or a property: wrapped by one that records who reads
    require = cls.require_world

    def get(self):
        reads.append(self.where)
        return slot.__get__(self, cls)

    def recorded_require(self):
        reads.append(self.where)
        return require(self)

    monkeypatch.setattr(cls, "world", property(get, lambda self, value: slot.__set__(self, value)))
    monkeypatch.setattr(cls, "require_world", recorded_require)
    cfg = load_scenario("forest_global")
    assert cfg.planner.kind == "global"
    build_simulation(cfg)
    assert not [w for w in reads if w.startswith("planner")], reads
    known = {
        "name": "known",
        "vehicle": "cu_astro",
        "world": {"kind": "forest", "seed": 3, "n_trees": 60, "size": 16.0, "clearing": 1.0},
        "planner": {"kind": "global_known_map", "goal": [7.0, 0.5, 1.5]},
        "start_p_W": [-7.0, 0.0, 0.0],
    }
    build_simulation(ScenarioConfig.from_dict(known))
    assert [w for w in reads if w.startswith("planner")]  # the probe sees a read when there is one

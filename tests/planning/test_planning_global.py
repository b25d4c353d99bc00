"""The global chain (path search -> clearance-keeping min-snap) and the ``global_known_map`` planner kind: every
sample of the trajectory clears the world's triangles by the radius, measured by Open3D's exact distance
(independent of the distance field the planner used); the chain is usable from a scenario YAML, flown alone or as
the local replanner's guide. forest_global flies the ``global`` kind on the map built online (its own tests:
test_planning_global_online.py)."""

from __future__ import annotations

import numpy as np
import pytest

from cufund import ScenarioConfig, load_scenario
from cufund.core.components import Component
from cufund.core.config import ConfigError
from cufund.planning import clearance_from_world
from cufund.planning.diagnostics import PLANNER_DIAGNOSTICS
from cufund.planning.global_planner import GlobalPlanner, GlobalPlannerParams
from cufund.scenarios.build import build_simulation, run_scenario
from cufund.worlds.builtin import forest

o3d = pytest.importorskip("open3d")

RADIUS = 0.3
BOUNDS = np.array([[-9.0, -9.0, 0.0], [9.0, 9.0, 3.0]])
START, GOAL = np.array([-7.0, 0.0, 1.5]), np.array([7.0, 0.5, 1.5])


def _truth(world):
    scene = o3d.t.geometry.RaycastingScene()
    for o in world.objects:
        scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    return lambda p: scene.compute_distance(np.asarray(p, np.float32).reshape(-1, 3)).numpy().astype(float)


@pytest.fixture(scope="module")
def setting():
    world = forest(seed=3, n_trees=60, size=16.0, clearing=1.0)
    return world, clearance_from_world(world, 0.1, BOUNDS), _truth(world)


def _check(plan, truth):
    assert plan.ok, plan.status
    traj = plan.trajectory
    s = traj.sample(np.arange(traj.t_start, traj.t_end + 1e-9, 0.005))
    assert truth(s.p_W).min() >= RADIUS  # the trajectory itself, not only its waypoints
    assert truth(plan.path.path_W).min() >= RADIUS
    np.testing.assert_allclose(s.p_W[0], START, atol=1e-9)
    ends = traj.sample(np.array([traj.t_start, traj.t_end]))
    np.testing.assert_allclose(ends.p_W, [START, GOAL], atol=1e-9)
    assert np.abs(ends.v_W).max() < 1e-9  # at rest at both ends
    # within the limits up to the time scaling's sampling (16 samples per segment: a peak between two samples may
    # pass the bound; measured up to 0.52 % over on an OMPL path, whose shape varies from run to run)
    assert plan.motion.feasibility.within(v_max=2.0, a_max=3.0, rel_tol=1e-2)
    return s.p_W


def test_astar_chain_keeps_the_radius_and_is_deterministic(setting):
    _, q, truth = setting
    line = np.linspace(START, GOAL, 400)
    assert truth(line).min() < RADIUS  # the straight line is blocked: the chain had to go round
    planner = GlobalPlanner(GlobalPlannerParams(radius=RADIUS))
    a = planner.plan(q, START, GOAL)
    pa = _check(a, truth)
    b = GlobalPlanner(GlobalPlannerParams(radius=RADIUS)).plan(q, START, GOAL)
    np.testing.assert_array_equal(
        pa, b.trajectory.sample(np.arange(b.trajectory.t_start, b.trajectory.t_end + 1e-9, 0.005)).p_W
    )


@pytest.mark.parametrize("search", ["rrt_connect", "informed_rrt_star"])
def test_ompl_chain_keeps_the_radius(setting, search):
    _, q, truth = setting
    plan = GlobalPlanner(GlobalPlannerParams(search=search, radius=RADIUS, improve_time=0.3)).plan(q, START, GOAL)
    _check(plan, truth)


def test_chain_failures_and_params(setting):
    world, q, _ = setting
    trunk = next(o for o in world.objects if o.label == "tree")
    inside = np.r_[trunk.vertices[:, :2].mean(axis=0), 1.0]
    plan = GlobalPlanner(GlobalPlannerParams(radius=RADIUS)).plan(q, START, inside)
    assert plan.status == "goal_blocked" and plan.trajectory is None and not plan.ok
    with pytest.raises(ConfigError, match="search must be one of astar, rrt_connect"):
        GlobalPlannerParams(search="dijkstra")
    with pytest.raises(ConfigError, match="improve_time must be > 0"):
        GlobalPlannerParams(search="bit_star", improve_time=0.0)
    with pytest.raises(TypeError, match="query must be a ClearanceQuery"):
        GlobalPlanner().plan(np.zeros((3, 3, 3)), START, GOAL)


def _yaml_scenario(**planner):
    """A forest with no sensors: the min-snap from the known (true) geometry is flown as it is."""
    return ScenarioConfig.from_dict(
        {
            "name": "global_test",
            "vehicle": "cu_astro",
            "world": {"kind": "forest", "seed": 3, "n_trees": 60, "size": 16.0, "clearing": 1.0},
            "planner": {"kind": "global_known_map", "goal": GOAL.tolist(), **planner},
            "start_p_W": [START[0], START[1], 0.0],
            "duration": 40.0,
        }
    )


def _trunks(world):
    scene = o3d.t.geometry.RaycastingScene()
    for o in world.objects:
        if o.label == "tree":
            scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    return lambda p: scene.compute_distance(np.asarray(p, np.float32).reshape(-1, 3)).numpy().astype(float)


def test_global_kind_flies_the_chain_from_yaml(setting):
    world, _, _ = setting
    run = run_scenario(_yaml_scenario(radius=RADIUS))
    m = run.metrics
    assert m["status"] == "completed" and m["success"], m
    assert m["global_status"] == "ok" and m["global_search"] == "astar" and m["replans"] == 1
    p = run.result.states["p_W"]
    assert _trunks(world)(p).min() >= RADIUS  # flown: true states to the true trunks (the ground is landed on)
    assert np.linalg.norm(p[-1] - [GOAL[0], GOAL[1], 0.0]) < 0.05  # landed below the goal
    assert m["global_peak_speed_mps"] <= 2.0 * 1.005 and m["global_min_map_clearance_m"] >= RADIUS


def test_global_kind_plans_with_ompl_from_yaml(setting):
    _, _, truth = setting
    built = build_simulation(_yaml_scenario(search="rrt_connect", radius=RADIUS))
    path = built.context.tracking_path  # the min-snap part of the reference
    assert truth(path.sample(np.arange(path.t_start, path.t_end, 0.005)).p_W).min() >= RADIUS


def test_global_kind_rejects_bad_settings():
    with pytest.raises(ConfigError, match="planner.search must be one of"):
        build_simulation(_yaml_scenario(search="prm"))
    with pytest.raises(ConfigError, match="planner.local must be true or false"):
        build_simulation(_yaml_scenario(local="yes"))
    with pytest.raises(ConfigError, match="/map/esdf"):  # the replanner's map has no publisher
        build_simulation(_yaml_scenario(local=True))
    trunk = next(o for o in forest(seed=3, n_trees=60, size=16.0, clearing=1.0).objects if o.label == "tree")
    with pytest.raises(ConfigError, match=r"no astar plan .* \(goal_blocked\)"):  # a goal inside a trunk
        build_simulation(_yaml_scenario(goal=[*trunk.vertices[:, :2].mean(axis=0).tolist(), 1.0]))


class DiagnosticsLog(Component):
    """Keeps every message on /planner/diagnostics."""

    name = "diagnostics_log"
    rate_hz = 50.0
    inputs = (PLANNER_DIAGNOSTICS,)

    def reset(self) -> None:
        self.seen: list = []

    def setup(self, bus) -> None:
        self.sub = bus.subscribe(PLANNER_DIAGNOSTICS)

    def step(self, t, bus) -> None:
        self.seen += self.sub.take()


def test_forest_global_scenario_guides_the_local_replanner():
    """forest_global (shortened like test_forest, on ground truth to keep it short): the local replanner, guided
    by the global path searched on the map built online, crosses to the goal clear of the trunks."""
    cfg = load_scenario("forest_global")
    assert cfg.planner.kind == "global" and cfg.planner.params.local and cfg.estimator is not None  # on the LIO
    cfg = cfg.with_overrides(
        {
            "estimator": None,
            "world.seed": 1,
            "world.size": 24.0,
            "world.n_trees": 87,
            "planner.goal": [12.0, 0.0, 1.5],
            "mapper.size": [18.0, 12.0, 4.0],
            "mapper.origin_W": [-3.0, -6.0, -0.5],
            "duration": 30.0,
        }
    )
    world = build_simulation(cfg).context.world
    log = DiagnosticsLog()
    run = run_scenario(cfg, extra_components=(log,))
    m = run.metrics
    assert m["status"] == "completed" and m["success"] and m["global_status"] == "ok", m
    # every replan's diagnostics were published (the last may be still in flight at the end), the global ones too
    local = [d for d in log.seen if d.planner == "local"]
    glob = [d for d in log.seen if d.planner == "global"]
    assert len(local) + len(glob) == len(log.seen)
    assert m["replans"] - 1 <= len(local) <= m["replans"]
    assert {d.status for d in local} <= set(m["replan_status"])
    assert len(glob) == sum(m["global_replan_status"].values()) and m["global_replans"] >= 2  # replanned online
    ok = [d for d in local if d.status == "ok"]
    assert min(d.min_clearance_m for d in ok) == pytest.approx(m["plan_min_map_clearance_m"])
    assert m["replans"] > 50 and m["global_path_length_m"] > 12.0 and m["global_abort"] is None
    assert _trunks(world)(run.result.states["p_W"]).min() >= RADIUS

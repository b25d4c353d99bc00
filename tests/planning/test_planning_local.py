"""The B-spline local replanner: continuity where a replan joins, an obstacle appearing mid-flight
avoided (checked by brute-force distance to the obstacle boxes, independent of the ESDF), the goal
reached at rest."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.mapping import EsdfMap, EsdfMapParams
from cufund.planning.bspline import UniformBspline, start_control_points
from cufund.planning.local_planner import BsplineLocalPlanner, LocalPlannerParams

RES = 0.1
ORIGIN = np.array([-1.0, -3.0, 0.0])
PILLAR = (np.array([4.0, -0.3, 0.0]), np.array([4.6, 0.3, 3.0]))  # [min, max] corners, whole voxels
GOAL = np.array([10.0, 0.0, 1.5])


def _box_distance(p, lo, hi):
    return np.linalg.norm(np.maximum(np.maximum(lo - p, 0.0), p - hi), axis=1)


def _truth(p):
    """Distance to the floor voxels (z < 0.1) and the pillar, from the boxes themselves."""
    return np.minimum(p[:, 2] - RES, _box_distance(p, *PILLAR))


def _map():
    m = EsdfMap(EsdfMapParams(resolution=RES, size=(12, 6, 3), origin_W=tuple(ORIGIN), nthreads=1))
    m.set_occupied(np.argwhere(np.ones((120, 60, 1), bool)))  # the floor
    return m


def _add_pillar(m):
    lo = np.round((PILLAR[0] - ORIGIN) / RES).astype(int)
    hi = np.round((PILLAR[1] - ORIGIN) / RES).astype(int)
    m.set_occupied(np.argwhere(np.ones(hi - lo, bool)) + lo)


def test_bspline_starts_at_the_given_state_and_is_c2():
    rng = np.random.default_rng(0)
    p, v, a = rng.normal(size=(3, 3))
    q = np.vstack([start_control_points(p, v, a, 0.2), rng.normal(size=(6, 3))])
    tr = UniformBspline(q, 0.2, t_start=1.0)
    s = tr.sample(1.0)
    np.testing.assert_allclose([s.p_W[0], s.v_W[0], s.a_W[0]], [p, v, a], atol=1e-12)
    knots = 1.0 + 0.2 * np.arange(1, q.shape[0] - 3)
    for r in range(3):  # continuous position, velocity, acceleration at the knots
        np.testing.assert_allclose(tr.derivative(knots - 1e-9, r), tr.derivative(knots + 1e-9, r), atol=1e-6)
    t = np.linspace(1.1, tr.t_end - 0.1, 50)
    np.testing.assert_allclose(
        (tr.derivative(t + 1e-6, 0) - tr.derivative(t - 1e-6, 0)) / 2e-6, tr.derivative(t, 1), atol=1e-6
    )


def test_replan_avoids_an_obstacle_that_appears_mid_flight():
    m = _map()
    lp = BsplineLocalPlanner(m, LocalPlannerParams(radius=0.3))
    first = lp.replan(0.0, [0.0, 0.0, 1.5], np.zeros(3), np.zeros(3), GOAL)
    assert first.status == "ok"
    _add_pillar(m)  # seen by the sensor after the first plan
    tr1 = first.trajectory
    s1 = tr1.sample(np.linspace(tr1.t_start, tr1.t_end, 2000)).p_W
    assert _truth(s1).min() < 0.3  # the old plan now runs into the pillar
    t_r = 1.0
    s = tr1.sample(t_r)
    second = lp.replan(t_r, s.p_W[0], s.v_W[0], s.a_W[0], GOAL)
    assert second.status == "ok"
    tr2 = second.trajectory
    j = tr2.sample(t_r)
    np.testing.assert_allclose([j.p_W[0], j.v_W[0], j.a_W[0]], [s.p_W[0], s.v_W[0], s.a_W[0]], atol=1e-9)
    p2 = tr2.sample(np.linspace(tr2.t_start, tr2.t_end, 4000)).p_W
    assert _truth(p2).min() >= 0.3 - 1e-9
    assert second.min_clearance >= 0.3


def test_receding_horizon_reaches_the_goal_continuously():
    m = _map()
    par = LocalPlannerParams(radius=0.3, v_max=2.0, a_max=3.0)
    lp = BsplineLocalPlanner(m, par)
    t, p, v, a = 0.0, np.array([0.0, 0.2, 1.2]), np.zeros(3), np.zeros(3)
    flown = []
    plan = None
    for step in range(200):  # replans at 10 Hz
        if step == 10:
            _add_pillar(m)
        new = lp.replan(t, p, v, a, GOAL)
        if new.status == "ok":
            if plan is not None:  # the new trajectory joins the flown one with no jump
                np.testing.assert_allclose(new.trajectory.sample(t).p_W[0], p, atol=1e-9)
                np.testing.assert_allclose(new.trajectory.sample(t).v_W[0], v, atol=1e-9)
                np.testing.assert_allclose(new.trajectory.sample(t).a_W[0], a, atol=1e-9)
            plan = new.trajectory
        assert plan is not None
        if new.reaches_goal and new.status == "ok":
            tail = plan.sample(np.linspace(t, plan.t_end, 500))
            flown.append(tail.p_W)
            break
        seg = plan.sample(np.linspace(t, t + 0.1, 11))
        flown.append(seg.p_W)
        t += 0.1
        s = plan.sample(t)
        p, v, a = s.p_W[0], s.v_W[0], s.a_W[0]
    else:
        pytest.fail("the goal was not reached in 20 s")
    path = np.vstack(flown)
    np.testing.assert_allclose(path[-1], GOAL, atol=1e-9)
    assert _truth(path).min() >= 0.3 - 1e-9
    end = plan.sample(plan.t_end)
    assert np.linalg.norm(end.v_W) < 1e-9 and np.linalg.norm(end.a_W) < 1e-9


def test_params_are_checked():
    with pytest.raises(ConfigError, match="radius must be a finite number > 0"):
        LocalPlannerParams(radius=0.0)
    with pytest.raises(ConfigError, match="max_iterations must be an integer >= 1"):
        LocalPlannerParams(max_iterations=0)
    with pytest.raises(ConfigError, match="retries must be an integer in 0..8"):
        LocalPlannerParams(retries=-1)
    with pytest.raises(TypeError, match="esdf_map must be a cufund.mapping.EsdfMap"):
        BsplineLocalPlanner(None)


def test_guide_stays_in_the_flight_band_over_unobserved_ground():
    """A wall from 0.8 m up with no floor mapped under it (unobserved ground is free to the map): the shortest way
    ducks under it, into the ground. With the band [0.5, 3] m every accepted trajectory stays in it."""
    m = EsdfMap(EsdfMapParams(resolution=RES, size=(12, 6, 3), origin_W=(-1.0, -3.0, -0.5), nthreads=1))
    # wall x in [4, 4.4], y in [-1.5, 3], z in [0.8, 2.5]: voxel z index from (0.8 + 0.5) / 0.1 = 13; the way
    # round is its end at y = -1.5
    m.set_occupied(np.argwhere(np.ones((4, 45, 17), bool)) + [50, 15, 13])
    start, goal = np.array([0.0, 0.0, 1.0]), np.array([9.0, 0.0, 1.0])
    low = BsplineLocalPlanner(m, LocalPlannerParams(radius=0.3, z_min=-1.0)).replan(
        0.0, start, np.zeros(3), np.zeros(3), goal
    )
    assert (
        low.status == "ok"
        and low.trajectory.sample(np.linspace(low.trajectory.t_start, low.trajectory.t_end, 500)).p_W[:, 2].min() < 0.3
    )  # ducks under
    lp = BsplineLocalPlanner(m, LocalPlannerParams(radius=0.3))
    t, p, v, a = 0.0, start, np.zeros(3), np.zeros(3)
    flown = []
    for _ in range(150):  # receding horizon at 10 Hz, perfect tracking
        r = lp.replan(t, p, v, a, goal)
        assert r.status == "ok", r.status
        tr = r.trajectory
        assert tr.sample(np.linspace(tr.t_start, tr.t_end, 500)).p_W[:, 2].min() >= 0.5 - 0.05
        if r.reaches_goal:
            flown.append(tr.sample(np.linspace(t, tr.t_end, 300)).p_W)
            break
        flown.append(tr.sample(np.linspace(t, t + 0.1, 11)).p_W)
        t += 0.1
        s = tr.sample(t)
        p, v, a = s.p_W[0], s.v_W[0], s.a_W[0]
    assert r.reaches_goal
    f = np.vstack(flown)
    wall = (np.array([4.0, -1.5, 0.8]), np.array([4.4, 3.0, 2.5]))
    assert _box_distance(f, *wall).min() >= 0.3 - 1e-9 and f[:, 2].min() >= 0.45  # round the wall's end
    with pytest.raises(ConfigError, match="z_max must be > z_min"):
        LocalPlannerParams(z_min=2.0, z_max=1.0)


def test_short_leg_between_offset_tunnel_frames_is_planned_from_rest():
    """Tunnel course 61, frame 4 to 5 (0.62 m, 0.33 m sideways and 0.17 m up): the guide bends at the radius
    there, and the first control-point spacing leaves too few points for a rest-to-rest move; the replan
    retries with denser control points and is certified. Clearance re-measured by Open3D's exact distance
    to the frames' triangles."""
    import open3d as o3d

    from cufund.missions.tunnel_course import tunnel_course_layout
    from cufund.planning import esdf_from_world

    c = tunnel_course_layout(61)
    start, goal = (np.asarray(c.frames[k].centre_W, float) for k in (3, 4))
    lo, hi = np.minimum(start, goal) - 1.0, np.maximum(start, goal) + 1.0
    esdf = esdf_from_world(c.world, 0.025, np.stack([lo, hi]))
    params = LocalPlannerParams(
        radius=0.15, margin=0.15, v_max=1.5, a_max=2.0, dt=0.1, horizon=4.0, z_min=lo[2] + 0.5, z_max=hi[2] - 0.5
    )
    r = BsplineLocalPlanner(esdf, params).replan(0.0, start, np.zeros(3), np.zeros(3), goal)
    assert r.status == "ok" and r.reaches_goal
    scene = o3d.t.geometry.RaycastingScene()
    for o in c.world.objects:
        scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    p = r.trajectory.sample(np.linspace(r.trajectory.t_start, r.trajectory.t_end, 400)).p_W
    assert scene.compute_distance(p.astype(np.float32)).numpy().min() >= 0.15 - 1e-4
    np.testing.assert_allclose(p[-1], goal, atol=1e-9)

"""The local planner kind in the simulator: trajectory updates stitched with no jump in position, velocity or
acceleration, and an obstacle that appears in the map mid-flight avoided (checked by the distance of the true
states to the obstacle box itself, not the ESDF)."""

from __future__ import annotations

import numpy as np
import pytest

from cufund import ScenarioConfig
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.planning.bspline import UniformBspline
from cufund.planning.local_planner_component import LocalPlannerComponent
from cufund.planning.sequence import Hold, TrajectorySequence
from cufund.planning.trajectory_follower import stitched
from cufund.scenarios.build import build_simulation, run_built
from planning_support import GAINS, PILLAR, ScriptedMap, UpdateLog


def _config(**planner):
    return ScenarioConfig.from_dict(
        {
            "name": "local_test",
            "vehicle": "cu_astro",
            "start_p_W": [0.0, 0.0, 0.0],
            "duration": 25.0,
            "planner": {"kind": "local", "goal": [8.0, 0.0, 1.5], "v_max": 1.5, **planner},
            "controller": {"kind": "pid", **GAINS},
            "rates": {"physics_hz": 1000, "trajectory_hz": 250, "position_hz": 250, "attitude_hz": 250, "rate_hz": 500},
        }
    )


def _fly(t_appear):
    probe = UpdateLog()
    mapper = ScriptedMap(PILLAR, t_appear)
    built = build_simulation(_config(), extra_components=(mapper, probe))
    assert Topics.TRAJECTORY_SETPOINT in built.simulator.record_topics  # every setpoint kept
    run = run_built(built)
    planner = next(c for c in built.simulator.components if isinstance(c, LocalPlannerComponent))
    return run, planner, probe


@pytest.fixture(scope="module")
def pillar_flight():
    return _fly(t_appear=6.5)


def _box_distance(p, lo, hi):
    return np.linalg.norm(np.maximum(np.maximum(lo - p, 0.0), p - hi), axis=1)


def test_stitched_setpoints_are_continuous(pillar_flight):
    run, planner, probe = pillar_flight
    sp = run.result.topics[str(Topics.TRAJECTORY_SETPOINT)]
    t = np.asarray(sp["t"])
    p, v, a, j = (np.asarray(sp[k]) for k in ("p_W", "v_W", "a_W", "j_W"))
    assert len(probe.updates) > 50  # replanned at 10 Hz all the way
    dt = np.diff(t)
    assert np.allclose(dt, 1 / 250, atol=1e-9)

    # Between consecutive setpoints each quantity can change by at most its derivative's bound times the tick
    # (mean value theorem): a jump at a stitch would break these.
    def n(x):
        return np.linalg.norm(x, axis=1)

    a_max, j_max = n(a).max(), n(j).max()
    assert np.all(n(np.diff(p, axis=0)) <= (np.maximum(n(v)[:-1], n(v)[1:]) + a_max * dt) * dt + 1e-9)
    assert np.all(n(np.diff(v, axis=0)) <= (np.maximum(n(a)[:-1], n(a)[1:]) + j_max * dt) * dt + 1e-9)
    assert np.all(n(np.diff(a, axis=0)) <= 1.05 * j_max * dt + 1e-9)
    # and exactly: every update starts from the reference it replaces at its own start time
    ref = planner.initial
    for msg in probe.updates:
        tr = msg.trajectory
        old, new = ref.sample(tr.t_start), tr.sample(tr.t_start)
        for k in ("p_W", "v_W", "a_W"):
            np.testing.assert_allclose(getattr(new, k), getattr(old, k), atol=1e-9)
        ref = stitched(ref, tr, msg.t)


def test_an_obstacle_appearing_mid_flight_is_avoided(pillar_flight):
    run, planner, probe = pillar_flight
    m = run.metrics
    assert m["status"] == "completed" and m["goal_reached"], m
    p = run.result.states["p_W"]
    assert np.linalg.norm(p[-1, :2] - [8.0, 0.0]) < 0.1 and p[-1, 2] < 0.05  # landed at the goal
    # The trajectory followed when the pillar appeared ran straight through it ...
    before = [u.trajectory for u in probe.updates if u.t < 6.5][-1]
    ts = np.linspace(before.t_start, before.t_start + before.duration, 400)
    assert _box_distance(before.sample(ts).p_W, *PILLAR).min() == 0.0
    # ... the flight kept the planner's radius from the box itself (true states, not the map)
    assert _box_distance(p, *PILLAR).min() >= planner.params.radius - 0.05
    assert m["plan_ms_median"] > 0 and m["replans"] == sum(m["replan_status"].values())


def test_stitching_keeps_only_parts_that_still_serve():
    a = Hold(np.zeros(3), 5.0, t_start=0.0)
    b = UniformBspline(np.tile([1.0, 0.0, 1.0], (5, 1)), 0.1, t_start=2.0)
    c = UniformBspline(np.tile([2.0, 0.0, 1.0], (5, 1)), 0.1, t_start=1.5)
    s = stitched(a, b, t=1.0)
    assert isinstance(s, TrajectorySequence) and s.parts == [a, b]
    s2 = stitched(s, c, t=1.2)  # c starts before b: b is dropped, a kept until c starts
    assert s2.parts == [a, c]
    assert stitched(s2, b, t=2.5) is b  # nothing before t is needed any more
    np.testing.assert_allclose(s2.sample(np.array([1.0, 1.6])).p_W, [[0, 0, 0], [2, 0, 1]])
    with pytest.raises(TypeError, match="Trajectory"):
        stitched(a, "not a trajectory", 0.0)


def test_local_kind_validates_its_params_and_needs_a_map():
    with pytest.raises(ConfigError, match="planner.goal"):
        build_simulation(_config(goal=[1.0, 2.0]))
    with pytest.raises(ConfigError, match="radius"):
        build_simulation(_config(radius=-1.0))
    with pytest.raises(ConfigError, match="/map/esdf"):
        build_simulation(_config())

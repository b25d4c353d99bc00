"""LTLf missions: the DFA against hand-worked traces, the product search against hand-worked visit orders,
the sequence fast path, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.planning.mission_spec import MissionSpec, Region, compile_ltlf

A, B, C = frozenset({"a"}), frozenset({"b"}), frozenset({"c"})
AB, NONE = frozenset({"a", "b"}), frozenset()


@pytest.mark.parametrize(
    "formula, word, accepted",
    [
        ("F(a & F(b))", [A, B], True),
        ("F(a & F(b))", [B, A], False),
        ("F(a & F(b))", [AB], True),  # F includes the present: a and then (now) b
        ("F(a & F(b))", [A, NONE, NONE], False),
        ("F(a) & G(!c)", [NONE, A], True),
        ("F(a) & G(!c)", [A, C], False),
        ("a U b", [A, A, B], True),
        ("a U b", [A, NONE, B], False),
        ("X(a)", [NONE, A], True),
        ("X(a)", [A, NONE], False),
    ],
)
def test_dfa_against_hand_worked_traces(formula, word, accepted):
    assert compile_ltlf(formula).accepts(word) is accepted


def _regions():
    return [
        Region("a", (4.0, 0.0, 1.0), size=(1.0, 1.0, 1.0)),
        Region("b", (1.0, 0.0, 1.0), radius=0.5),
        Region("c", (0.0, 5.0, 1.0), size=(1.0, 1.0, 1.0)),
        Region("home", (0.0, 0.0, 0.5), radius=0.3),
    ]


def test_product_search_takes_the_shortest_accepted_order():
    start = [0.0, 0.0, 1.0]
    # Either order is accepted: b (1 m away) then a (3 m further) = 4 m beats a then b (4 + 3 = 7 m).
    plan = MissionSpec.parse("F(a) & F(b)").plan(_regions(), start)
    assert plan.regions == ("b", "a") and plan.length == pytest.approx(4.0)
    # b may only be entered once a has been visited: a (4 m), then b (3 m).
    plan = MissionSpec.parse("F(b) & (!b U a)").plan(_regions(), start)
    assert plan.regions == ("a", "b") and plan.length == pytest.approx(7.0)
    np.testing.assert_array_equal(plan.waypoints_W, [[4.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
    # Return home at the end; c never.
    plan = MissionSpec.parse("F(a & F(home)) & G(!c)").plan(_regions(), start)
    assert plan.regions == ("a", "home") and plan.length == pytest.approx(4.0 + np.hypot(4.0, 0.5))


def test_plain_sequence_fast_path_agrees_with_the_dfa():
    formula = "F(c & F(a & F(b)))"
    fast = MissionSpec.parse(formula)
    assert fast.dfa is None and fast.sequence == ("c", "a", "b")
    slow = MissionSpec(formula, None, compile_ltlf(formula))
    p, q = fast.plan(_regions(), [0, 0, 1]), slow.plan(_regions(), [0, 0, 1])
    assert p.regions == q.regions and p.length == pytest.approx(q.length)
    assert MissionSpec.sequence_of(["a", "home"]).plan(_regions(), [0, 0, 1]).regions == ("a", "home")


def test_clear_errors():
    with pytest.raises(ConfigError, match="is unsatisfiable"):
        MissionSpec.parse("F(a) & G(!a)")
    with pytest.raises(ConfigError, match=r"unknown regions \['gate9'\]; declared: \['a', 'b', 'c', 'home'\]"):
        MissionSpec.parse("F(a) & F(gate9)").plan(_regions(), [0, 0, 1])
    with pytest.raises(ConfigError, match=r"unknown regions \['zz'\]"):
        MissionSpec.parse("F(a & F(zz))").plan(_regions(), [0, 0, 1])  # the fast path checks too
    with pytest.raises(ConfigError, match="no order of visits to the declared regions satisfies"):
        MissionSpec.parse("F(a & b)").plan(_regions(), [0, 0, 1])  # satisfiable, but a and b are disjoint
    with pytest.raises(ConfigError, match="cannot parse the LTLf formula"):
        MissionSpec.parse("F(a &")
    with pytest.raises(ConfigError, match="exactly one of size"):
        Region("x", (0, 0, 0))
    with pytest.raises(ConfigError, match="is not inside the region"):
        Region("x", (0, 0, 0), radius=1.0, waypoint_W=(2, 0, 0))


def test_mission_to_trajectory_through_a_tunnel_course():
    """Task -> path -> motion: the gates of a seeded tunnel course in an order the DFA forces, flown by a
    min-snap that keeps the radius from the course's triangles (Open3D) and threads every opening in turn."""
    o3d = pytest.importorskip("open3d")
    from cufund.missions.tunnel_course import tunnel_course_layout
    from cufund.planning import clearance_from_world, plan_mission_trajectory

    course = tunnel_course_layout(2)
    lo, hi = course.path_W.min(0) - 1.0, course.path_W.max(0) + 1.0
    lo[2] = 0.0
    q = clearance_from_world(course.world, 0.025, np.stack([lo, hi]))
    # Any order is allowed by the F's, the U's force gate k before gate k+1 (the shortest order is that one
    # anyway; the U's make the DFA, not the fast path, find it).
    spec = MissionSpec.parse("F(gate3) & F(gate1) & F(gate2) & (!gate2 U gate1) & (!gate3 U gate2)")
    assert spec.dfa is not None
    regions = course.regions()[:3]
    radius = 0.15
    m = plan_mission_trajectory(spec, regions, course.entry_W, q, radius=radius, v_max=1.0, a_max=2.0)
    assert m.mission.regions == ("gate1", "gate2", "gate3")
    tr = m.motion.trajectory
    s = tr.sample(np.linspace(tr.t_knots[0], tr.t_end, 20001))
    scene = o3d.t.geometry.RaycastingScene()
    for o in course.world.objects:
        scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    assert scene.compute_distance(s.p_W.astype(np.float32)).numpy().min() >= radius - 1e-5
    crossings = []
    for f in course.frames[:3]:
        side = (s.p_W - f.centre_W) @ f.axis_W
        assert side[0] < 0  # starts before the frame ...
        k = np.flatnonzero(side >= -1e-9)  # ... and reaches its plane (the mission ends on the last one's centre)
        assert k.size >= 1
        crossings.append(k[0])
        h = s.p_W[k[0]] - f.centre_W
        assert abs(h[2]) <= f.height / 2 and abs(h @ [-np.sin(f.yaw), np.cos(f.yaw), 0.0]) <= f.width / 2
    assert crossings == sorted(crossings)
    assert m.motion.feasibility.within(v_max=1.0 * 1.01, a_max=2.0 * 1.01)


def test_regions_from_a_world_yaml_mapping():
    r = Region.from_dict("landing", {"centre_W": [6, 0, 0.2], "radius": 0.5, "waypoint_W": [6, 0, 0.5]})
    assert r.radius == 0.5 and r.waypoint_W == (6.0, 0.0, 0.5) and r.contains([6.3, 0.0, 0.2])
    assert not r.contains([6.6, 0.0, 0.2])
    with pytest.raises(ConfigError, match="unknown key 'center' in region gate1"):
        Region.from_dict("gate1", {"center": [0, 0, 0], "radius": 1.0})

"""LTLf missions: the DFA against hand-worked traces, the product search against hand-worked visit orders,
the sequence fast path, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.config import ConfigError
from cufund.planning.mission_spec import MissionSpec, Region, compile_ltlf

A, B, C = frozenset({"a"}), frozenset({"b"}), frozenset({"c"})
AB, NONE = frozenset({"a", "b"}), frozenset()


@pytest.mark.parametrize("formula, word, accepted", [
    ("F(a & F(b))", [A, B], True),
    ("F(a & F(b))", [B, A], False),
    ("F(a & F(b))", [AB], True),          # F includes the present: a and then (now) b
    ("F(a & F(b))", [A, NONE, NONE], False),
    ("F(a) & G(!c)", [NONE, A], True),
    ("F(a) & G(!c)", [A, C], False),
    ("a U b", [A, A, B], True),
    ("a U b", [A, NONE, B], False),
    ("X(a)", [NONE, A], True),
    ("X(a)", [A, NONE], False),
])
def test_dfa_against_hand_worked_traces(formula, word, accepted):
    assert compile_ltlf(formula).accepts(word) is accepted


def _regions():
    return [Region("a", (4.0, 0.0, 1.0), size=(1.0, 1.0, 1.0)),
            Region("b", (1.0, 0.0, 1.0), radius=0.5),
            Region("c", (0.0, 5.0, 1.0), size=(1.0, 1.0, 1.0)),
            Region("home", (0.0, 0.0, 0.5), radius=0.3)]


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

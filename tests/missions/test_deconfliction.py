"""Deconfliction of planned trajectories (cufund.missions.deconfliction): the separations are checked on the
trajectories themselves with the test's own closed form (piecewise-linear motion: the closest approach of each
common interval), against the analytic delay of a crossing pair, and a head-on pair that collides without
deconfliction keeps the minimum separation with ORCA."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from cufund.missions.deconfliction import Trajectory, min_separation, orca, time_shift

D_MIN = 1.0


def closest_approach(a: Trajectory, b: Trajectory, samples_per_interval: int = 1) -> float:
    """The test's own: the smallest distance of two piecewise-linear trajectories (both held at their ends), from
    the minimum of |d0 + s (d1 - d0)| on each interval between the merged breakpoints."""
    t = np.union1d(a.t, b.t)

    def at(tr, tt):
        return np.array([np.interp(tt, tr.t, tr.p[:, k]) for k in range(3)]).T

    d = at(a, t) - at(b, t)
    best = np.inf
    for d0, d1 in zip(d[:-1], d[1:], strict=True):
        e = d1 - d0
        s = 0.0 if e @ e == 0 else np.clip(-(d0 @ e) / (e @ e), 0.0, 1.0)
        best = min(best, np.linalg.norm(d0 + s * e))
    return float(min(best, np.linalg.norm(d[-1])))


def test_min_separation_is_exact_against_dense_sampling():
    rng = np.random.default_rng(3)
    for _ in range(20):
        a = Trajectory(np.cumsum(rng.uniform(0.1, 2, 6)), rng.uniform(-5, 5, (6, 3)))
        b = Trajectory(np.cumsum(rng.uniform(0.1, 2, 5)), rng.uniform(-5, 5, (5, 3)))
        d, t = min_separation(a, b)
        ts = np.linspace(0, 15, 150001)
        dense = np.linalg.norm(a.at(ts) - b.at(ts), axis=1).min()
        assert d <= dense + 1e-12 and dense - d < 1e-3
        assert np.linalg.norm(a.at(t) - b.at(t)) == pytest.approx(d)


def test_a_crossing_pair_is_delayed_by_the_analytic_shift():
    # a along +x and b along +y through the origin at 1 m/s, both there at t = 10 s: with b started later by dt the
    # distance is sqrt((t - 10)^2 + (t - 10 - dt)^2), smallest dt / sqrt(2): it needs dt >= sqrt(2) d_min
    a = Trajectory.from_path([(-10, 0, 5), (10, 0, 5)], 1.0)
    b = Trajectory.from_path([(0, -10, 5), (0, 10, 5)], 1.0)
    assert closest_approach(a, b) == pytest.approx(0.0)
    step = 0.1
    delays = time_shift({"a": a, "b": b}, D_MIN, step=step)
    assert delays["a"] == 0.0
    need = math.sqrt(2) * D_MIN
    assert need <= delays["b"] < need + step
    assert closest_approach(a, b.shifted(delays["b"])) >= D_MIN
    # priority reversed: a waits instead
    delays = time_shift({"a": a, "b": b}, D_MIN, priority=["b", "a"], step=step)
    assert delays["b"] == 0.0 and need <= delays["a"] < need + step


def test_time_shifting_cannot_swap_a_head_on_pair():
    a = Trajectory.from_path([(-10, 0, 5), (10, 0, 5)], 1.0)
    b = Trajectory.from_path([(10, 0, 5), (-10, 0, 5)], 1.0)
    with pytest.raises(ValueError, match="b keeps no 1.0 m separation from a"):
        time_shift({"a": a, "b": b}, D_MIN, max_delay=60.0)


def test_a_head_on_pair_keeps_the_minimum_separation_with_orca():
    paths = {"a": [(-10, 0, 5), (10, 0, 5)], "b": [(10, 0, 5), (-10, 0, 5)]}
    straight = {n: Trajectory.from_path(p, 1.0) for n, p in paths.items()}
    assert closest_approach(straight["a"], straight["b"]) == 0.0  # as planned they collide at the middle
    r = orca(paths, D_MIN, speed=1.0)
    assert r.reached == {"a": True, "b": True}
    ta, tb = r.trajectories["a"], r.trajectories["b"]
    assert closest_approach(ta, tb) >= D_MIN
    for tr, goal in ((ta, paths["a"][-1]), (tb, paths["b"][-1])):
        assert np.linalg.norm(tr.p[-1] - goal) <= 0.05
        speeds = np.linalg.norm(np.diff(tr.p, axis=0), axis=1) / np.diff(tr.t)
        assert speeds.max() <= 1.0 + 1e-9  # never faster than asked
    assert ta.t_end < 30.0  # passed each other, no standstill


def test_orca_keeps_six_vehicles_swapping_across_a_circle_apart():
    n = 6
    paths = {
        f"v{i}": [
            (8 * math.cos(2 * math.pi * i / n), 8 * math.sin(2 * math.pi * i / n), 5),
            (-8 * math.cos(2 * math.pi * i / n), -8 * math.sin(2 * math.pi * i / n), 5),
        ]
        for i in range(n)
    }
    r = orca(paths, D_MIN, speed=1.0)
    assert all(r.reached.values())
    for a, b in itertools.combinations(r.trajectories.values(), 2):
        assert closest_approach(a, b) >= D_MIN


def test_bad_input_is_refused():
    a = Trajectory.from_path([(0, 0, 1), (1, 0, 1)], 1.0)
    with pytest.raises(ValueError, match="priority"):
        time_shift({"a": a}, 1.0, priority=["b"])
    with pytest.raises(ValueError, match="speed"):
        Trajectory.from_path([(0, 0, 1)], 0.0)
    with pytest.raises(ValueError, match="min_sep"):
        orca({"a": [(0, 0, 1)]}, float("nan"), 1.0)
    with pytest.raises(ValueError, match="decrease"):
        Trajectory(np.array([1.0, 0.0]), np.zeros((2, 3)))

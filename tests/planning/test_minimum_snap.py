"""Min-snap trajectories: waypoints, continuity, optimality against RotorPy's QP, time allocation, inputs."""

import numpy as np
import pytest

from cufund.planning import JerkLimitedMove, MinimumSnapTrajectory, MinSnapPlanner, MinSnapPlannerParams
from cufund.planning.minimum_snap import optimize_segment_times

SQUARE = np.array([[0, 0, 1.5], [1, 0, 1.5], [1, 1, 1.5], [0, 1, 1.5], [0, 0, 1.5]], dtype=float)


def _rotorpy_snap_cost(traj) -> float:
    """sum over segments and axes of int (x'''')^2 dt, integrated exactly from RotorPy's own polynomials."""
    c = 0.0
    for i, dt in enumerate(traj.delta_t):
        for d in range(3):
            s = np.polyder(traj.x_poly[i, d], 4)
            integral = np.polyint(np.polymul(s, s))
            c += np.polyval(integral, dt) - np.polyval(integral, 0.0)
    return c


def test_passes_through_waypoints_at_rest_ends():
    tr = MinimumSnapTrajectory(SQUARE, yaw=[0, 0.5, 1.0, 1.5, 2.0], durations=[2, 2, 2, 2], t_start=1.0)
    s = tr.sample(tr.t_knots)
    np.testing.assert_allclose(s.p_W, SQUARE, atol=1e-12)
    np.testing.assert_allclose(s.yaw, [0, 0.5, 1.0, 1.5, 2.0], atol=1e-12)
    for r in (1, 2, 3):
        np.testing.assert_allclose(tr.derivative(tr.t_knots[[0, -1]], r), 0.0, atol=1e-12)
    assert tr.sample(tr.t_knots[[0, -1]]).yaw_rate == pytest.approx([0.0, 0.0], abs=1e-12)


@pytest.mark.parametrize("r", range(7))
def test_continuous_through_snap_and_beyond(r):
    """The optimum is C^6 at interior waypoints (Euler-Lagrange); in particular continuous to snap (r = 4)."""
    rng = np.random.default_rng(1)
    w = rng.uniform(-3, 3, (8, 3))
    tr = MinimumSnapTrajectory(w, durations=rng.uniform(0.5, 2.0, 7))
    tk = tr.t_knots[1:-1]
    eps = 1e-7
    jump = np.abs(tr.derivative(tk - eps, r) - tr.derivative(tk + eps, r)).max()
    scale = max(1.0, np.abs(tr.derivative(tk, r)).max())
    assert jump < 1e-4 * scale


@pytest.mark.parametrize("n", [5, 12])
def test_snap_cost_no_larger_than_rotorpy(n):
    from rotorpy.trajectories.minsnap import MinSnap

    rng = np.random.default_rng(n)
    w = SQUARE if n == 5 else np.cumsum(rng.uniform(-1.5, 1.5, (n, 3)), axis=0) + [0, 0, 3]
    ref = MinSnap(w, v_avg=1.0, v_max=100.0, verbose=False)  # the speed bound inactive: same problem
    ours = MinimumSnapTrajectory(w, durations=ref.delta_t)
    theirs = _rotorpy_snap_cost(ref)
    assert ours.snap_cost() <= theirs * (1 + 1e-9)
    # the optimum is unique, so the two trajectories coincide
    t = np.linspace(0, ref.delta_t.sum(), 300)
    np.testing.assert_allclose(ours.sample(t).p_W, [ref.update(x)["x"] for x in t], atol=1e-6)


def test_snap_cost_matches_numerical_integral():
    tr = MinimumSnapTrajectory(SQUARE, durations=[1.0, 2.0, 1.5, 1.0])
    t = np.linspace(tr.t_knots[0], tr.t_end, 200001)
    snap = tr.derivative(t, 4)
    numeric = (
        np.trapezoid(np.sum(snap**2, axis=1), t) if hasattr(np, "trapezoid") else np.trapz(np.sum(snap**2, axis=1), t)
    )
    assert tr.snap_cost() == pytest.approx(numeric, rel=1e-6)


def test_time_allocation_meets_limits():
    for v_max, a_max in ((1.0, 2.0), (3.0, 1.0)):
        tr = MinimumSnapTrajectory(SQUARE * 3, v_max=v_max, a_max=a_max)
        s = tr.sample(np.linspace(tr.t_knots[0], tr.t_end, 20001))
        v = np.linalg.norm(s.v_W, axis=1).max()
        a = np.linalg.norm(s.a_W, axis=1).max()
        assert v <= v_max * 1.01 and a <= a_max * 1.01
        assert max(v / v_max, a / a_max) > 0.97  # one of the limits is reached: not needlessly slow


def test_vectorised_equals_scalar():
    tr = MinimumSnapTrajectory(SQUARE, v_max=1.0, a_max=2.0)
    t = np.linspace(-1, tr.t_end + 1, 50)
    s = tr.sample(t)
    for k, tk in enumerate(t):
        one = tr.sample(tk)
        np.testing.assert_allclose(one.p_W[0], s.p_W[k], atol=1e-14)
        np.testing.assert_allclose(one.a_W[0], s.a_W[k], atol=1e-14)
    # outside the span: holds the end points at rest
    np.testing.assert_allclose(s.p_W[0], SQUARE[0], atol=1e-12)
    np.testing.assert_allclose(s.v_W[-1], 0.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(waypoints_W=np.zeros((1, 3))), "shape"),
        (dict(waypoints_W=np.zeros((3, 2))), "shape"),
        (dict(waypoints_W=SQUARE, durations=[1, 1, 1]), "durations"),
        (dict(waypoints_W=SQUARE, durations=[1, 1, -1, 1]), "durations"),
        (dict(waypoints_W=SQUARE, yaw=[0, 1]), "yaw"),
        (dict(waypoints_W=np.array([[0, 0, 1], [0, 0, 1.0]])), "differ"),
        (dict(waypoints_W=np.array([[0, 0, np.nan], [0, 0, 1.0]])), "finite"),
    ],
)
def test_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        MinimumSnapTrajectory(**kwargs)


def test_jerk_limited_move_respects_limits():
    mv = JerkLimitedMove([0, 0, 0], [1, -2, 1.5], v_max=1.0, a_max=2.0, j_max=5.0, t_start=0.5)
    s = mv.sample(np.linspace(0, mv.t_end + 1, 4001))
    assert np.abs(s.v_W).max() <= 1.0 + 1e-9
    assert np.abs(s.a_W).max() <= 2.0 + 1e-9
    assert np.abs(s.j_W).max() <= 5.0 + 1e-6
    np.testing.assert_allclose(s.p_W[0], [0, 0, 0])
    np.testing.assert_allclose(s.p_W[-1], [1, -2, 1.5], atol=1e-12)
    # the position is the integral of the velocity
    dp = np.trapezoid(s.v_W, s.t, axis=0) if hasattr(np, "trapezoid") else np.trapz(s.v_W, s.t, axis=0)
    np.testing.assert_allclose(dp, [1, -2, 1.5], atol=1e-4)


@pytest.mark.parametrize("n", [5, 12])
def test_optimised_times_beat_rotorpy_at_its_own_total_time(n):
    from rotorpy.trajectories.minsnap import MinSnap

    rng = np.random.default_rng(n)
    w = SQUARE if n == 5 else np.cumsum(rng.uniform(-1.5, 1.5, (n, 3)), axis=0) + [0, 0, 3]
    ref = MinSnap(w, v_avg=1.0, v_max=100.0, verbose=False)
    T = optimize_segment_times(w, ref.delta_t)
    assert T.sum() == pytest.approx(ref.delta_t.sum(), rel=1e-12)
    ours = MinimumSnapTrajectory(w, durations=T)
    # measured: 0.47x (square) and 0.36x (12 random waypoints) of RotorPy's snap cost
    assert ours.snap_cost() <= 0.6 * _rotorpy_snap_cost(ref)
    # Optimal: no single time shift (at the same total) lowers the cost.
    for i in range(len(T) - 1):
        d = np.zeros_like(T)
        d[i], d[i + 1] = 1e-3 * T[i], -1e-3 * T[i]
        assert MinimumSnapTrajectory(w, durations=T + d).snap_cost() >= ours.snap_cost() * (1 - 1e-6)


@pytest.mark.parametrize("r", range(5))
def test_optimised_times_continuous_to_snap_and_within_limits(r):
    rng = np.random.default_rng(4)
    w = np.cumsum(rng.uniform(-1.5, 1.5, (7, 3)), axis=0)
    tr = MinimumSnapTrajectory(w, v_max=1.5, a_max=2.0, optimize_times=True)
    tk = tr.t_knots[1:-1]
    eps = 1e-7
    jump = np.abs(tr.derivative(tk - eps, r) - tr.derivative(tk + eps, r)).max()
    assert jump < 1e-4 * max(1.0, np.abs(tr.derivative(tk, r)).max())
    s = tr.sample(np.linspace(tr.t_knots[0], tr.t_end, 20001))
    v, a = np.linalg.norm(s.v_W, axis=1).max(), np.linalg.norm(s.a_W, axis=1).max()
    assert v <= 1.5 * 1.01 and a <= 2.0 * 1.01 and max(v / 1.5, a / 2.0) > 0.97
    assert tr.duration < MinimumSnapTrajectory(w, v_max=1.5, a_max=2.0).duration  # faster for the same limits


def _square_edge_distance(p):
    """Distance from points to the unit square's boundary at z = 1.5 (independent of the planner's code)."""
    x, y = np.clip(p[:, 0], 0, 1), np.clip(p[:, 1], 0, 1)
    inside = np.minimum.reduce([x, 1 - x, y, 1 - y])
    outside = np.hypot(p[:, 0] - x, p[:, 1] - y)
    return np.where(outside > 0, outside, inside) + 0 * p[:, 2]


@pytest.mark.parametrize("corridor", [0.15, 0.05])
@pytest.mark.parametrize("optimize", [False, True])
def test_corridor_keeps_the_square_near_its_edges(corridor, optimize):
    free = MinSnapPlanner(MinSnapPlannerParams(v_max=1.0, a_max=2.0, optimize_times=optimize)).plan(SQUARE)
    t = np.linspace(free.trajectory.t_knots[0], free.trajectory.t_end, 20001)
    assert _square_edge_distance(free.trajectory.sample(t).p_W).max() > 0.2  # without it: the bulge
    res = MinSnapPlanner(MinSnapPlannerParams(v_max=1.0, a_max=2.0, corridor=corridor, optimize_times=optimize)).plan(
        SQUARE
    )
    assert res.status == "ok" and res.inserted > 0
    tr = res.trajectory
    s = tr.sample(np.linspace(tr.t_knots[0], tr.t_end, 20001))
    assert _square_edge_distance(s.p_W).max() <= corridor
    assert np.abs(s.p_W[:, 2] - 1.5).max() < 1e-9
    np.testing.assert_allclose(tr.sample(tr.t_knots).p_W[[0, -1]], SQUARE[[0, -1]], atol=1e-12)
    assert res.feasibility.peak_speed <= 1.0 * 1.01


def test_feasibility_report_against_the_samples():
    tr = MinimumSnapTrajectory(SQUARE * 2, v_max=2.0, a_max=3.0)
    f = MinSnapPlanner(MinSnapPlannerParams(v_max=2.0, a_max=3.0, optimize_times=False)).plan(SQUARE * 2).feasibility
    s = tr.sample(np.linspace(tr.t_knots[0], tr.t_end, 50001))
    assert f.peak_speed == pytest.approx(np.linalg.norm(s.v_W, axis=1).max(), rel=1e-3)
    assert f.peak_acceleration == pytest.approx(np.linalg.norm(s.a_W, axis=1).max(), rel=1e-3)
    assert f.peak_jerk == pytest.approx(np.linalg.norm(s.j_W, axis=1).max(), rel=1e-3)
    # Planar flight at constant height: tilt = atan(|a| / g), thrust per mass = hypot(|a|, g).
    assert f.max_tilt_deg == pytest.approx(np.degrees(np.arctan(f.peak_acceleration / 9.81)), rel=1e-3)
    assert f.max_thrust_acceleration == pytest.approx(np.hypot(f.peak_acceleration, 9.81), rel=1e-4)
    assert f.within(v_max=2.0 * 1.01, a_max=3.0 * 1.01) and not f.within(v_max=1.5)


def test_snap_cost_gradient_is_exact():
    """dJ/dT_i = -H_i (the conserved 'energy' of the Euler-Lagrange solution) against central differences."""
    from cufund.planning.minimum_snap import snap_cost_and_gradient

    rng = np.random.default_rng(3)
    w = np.cumsum(rng.uniform(-1.5, 1.5, (7, 3)), axis=0)
    T = rng.uniform(0.5, 2.0, 6)
    J, g = snap_cost_and_gradient(w, T)
    assert J == pytest.approx(MinimumSnapTrajectory(w, durations=T).snap_cost(), rel=1e-12)
    h = 1e-6
    fd = [
        (snap_cost_and_gradient(w, T + h * e)[0] - snap_cost_and_gradient(w, T - h * e)[0]) / (2 * h) for e in np.eye(6)
    ]
    np.testing.assert_allclose(g, fd, rtol=1e-6)


@pytest.mark.parametrize(
    "values, durations, match",
    [
        (np.zeros((1, 3)), np.ones(0), "values"),
        (np.zeros((3, 3)), np.ones(3), "durations"),
        (np.zeros((3, 3)), [1.0, 0.0], "durations"),
        (np.zeros((3, 3)), [1.0, np.inf], "durations"),
        (np.array([[0, 0, 0], [1, np.nan, 0], [2, 0, 0.0]]), [1.0, 1.0], "finite"),
    ],
)
def test_core_spline_functions_reject_bad_input(values, durations, match):
    from cufund import _core

    for f in (
        lambda: _core.planning.min_derivative_spline(values, durations, 4),
        lambda: _core.planning.snap_cost_and_gradient(values, durations),
        lambda: _core.planning.optimize_segment_times(values, durations, 10, 1e-6),
    ):
        with pytest.raises(ValueError, match=match):
            f()

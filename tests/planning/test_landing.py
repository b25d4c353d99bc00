"""The landing reference: fast to just above the expected ground, slow on below it, resting there."""

import numpy as np
import pytest

from cufund.planning.landing import landing


def test_landing_descends_fast_then_slow_below_the_expected_ground():
    traj, t_end = landing(np.array([1.0, 2.0, 1.5]), 0.0, 0.5, 1.0, 3.0, 0.3, t_start=10.0)
    t = np.linspace(10.0, t_end + 5.0, 4000)
    s = traj.sample(t)
    assert np.allclose(s.p_W[:, :2], [1.0, 2.0]) and np.allclose(s.yaw, 0.3)
    assert s.p_W[0, 2] == pytest.approx(1.5) and s.p_W[-1, 2] == pytest.approx(-0.3)
    assert np.all(np.diff(s.p_W[:, 2]) <= 1e-12)  # only down
    low = s.p_W[:, 2] < 0.15 - 1e-6
    assert np.max(np.abs(s.v_W[low, 2])) <= 0.15 + 1e-6  # slow near and below the ground
    assert np.max(np.abs(s.v_W[:, 2])) == pytest.approx(0.5, rel=1e-3)
    assert t_end == pytest.approx(t[np.argmax(s.p_W[:, 2] <= -0.3 + 1e-9)], abs=0.01)


def test_a_landing_from_below_the_slow_height_is_all_slow():
    traj, t_end = landing(np.array([0.0, 0.0, 0.1]), 0.0, 0.5, 1.0, 3.0, 0.0, t_start=0.0)
    s = traj.sample(np.linspace(0.0, t_end, 500))
    assert np.max(np.abs(s.v_W[:, 2])) <= 0.15 + 1e-6

"""Gates-v0 against hand-computed cases: passing through the opening pays and moves on to the next gate (its
centre and normal in the observation); crossing the plane through the frame is a crash; far outside, nothing."""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest

import cufund.envs  # noqa: F401


def _fly_through(lateral: float, up: float = 0.0) -> tuple[gymnasium.vector.VectorEnv, float, bool]:
    v = gymnasium.make_vec("cufund/Gates-v0", num_envs=1, rewards={"progress": 0.0})
    v.reset(seed=0)
    g = np.asarray(v.config.targets[0])
    yaw = math.radians(g[3])
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    y = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    b = v.batch
    b.p[0] = g[:3] - 0.01 * n + lateral * y + up * np.array([0, 0, 1.0])
    b.v[0] = 2.0 * n  # 2 cm in the 10 ms step: across the plane
    b.w[0] = 0.0
    b.q[0] = (1.0, 0.0, 0.0, 0.0)
    _, r, te, _, _ = v.step(np.zeros((1, 4)))
    return v, float(r[0]), bool(te[0])


def test_through_the_opening_passes_the_gate() -> None:
    v, r, te = _fly_through(0.1, -0.1)
    assert v.target_index[0] == 1 and not te
    assert r > v.config.rewards.reached - 2.0
    g1 = np.asarray(v.config.targets[1])
    obs, *_ = v.step(np.zeros((1, 4)))
    np.testing.assert_array_equal(obs[0, 3:6], np.float32([math.cos(math.radians(45)), math.sin(math.radians(45)), 0]))
    np.testing.assert_array_equal(obs[0, :3], (g1[:3] - v.batch.p[0]).astype(np.float32))


@pytest.mark.parametrize(("lateral", "up"), [(0.4, 0.0), (0.0, -0.3), (-0.45, 0.45)])
def test_through_the_frame_is_a_crash(lateral: float, up: float) -> None:
    v, r, te = _fly_through(lateral, up)
    assert te and v.target_index[0] == 0
    assert r < -v.config.rewards.crash + 1.0


def test_far_beside_the_gate_nothing_happens() -> None:
    v, r, te = _fly_through(0.8)
    assert not te and v.target_index[0] == 0

"""Waypoints-v0 against hand-computed cases: reaching a waypoint pays the bonus and moves the observation's
target blocks on; the last one ends the episode (terminated, a success: no crash penalty); progress pays."""

from __future__ import annotations

import gymnasium
import numpy as np

import cufund.envs  # noqa: F401


def _place(v: gymnasium.vector.VectorEnv, p: tuple[float, float, float], vel: tuple[float, float, float]) -> None:
    b = v.batch
    b.p[0] = p
    b.v[0] = vel
    b.w[0] = 0.0
    b.q[0] = (1.0, 0.0, 0.0, 0.0)


def test_reaching_a_waypoint_pays_and_advances() -> None:
    v = gymnasium.make_vec("cufund/Waypoints-v0", num_envs=1)
    v.reset(seed=0)
    wp = np.asarray(v.config.targets)
    _place(v, (0.0, 0.0, 1.5), (0.0, 0.0, 0.0))
    obs, r, te, _, _ = v.step(np.zeros((1, 4)))
    assert v.target_index[0] == 1 and not te[0]
    p = v.batch.p[0]
    # blocks: waypoint 1 and 2 relative to the vehicle
    np.testing.assert_array_equal(obs[0, :3], (wp[1] - p).astype(np.float32))
    np.testing.assert_array_equal(obs[0, 3:6], (wp[2] - p).astype(np.float32))
    w = v.config.rewards
    d = np.linalg.norm(wp[0] - p)
    want = (
        w.alive
        - w.position * d
        - w.velocity * np.linalg.norm(v.batch.v[0])
        - w.rate * np.linalg.norm(v.batch.w[0])
        + w.progress * (0.0 - d)
        + w.reached
    )
    assert abs(r[0] - want) < 1e-9


def test_the_last_waypoint_ends_the_episode_without_penalty() -> None:
    v = gymnasium.make_vec("cufund/Waypoints-v0", num_envs=1)
    v.reset(seed=0)
    wp = np.asarray(v.config.targets)
    for k in range(len(wp)):
        _place(v, tuple(wp[k]), (0.0, 0.0, 0.0))
        _, r, te, _, _ = v.step(np.zeros((1, 4)))
        assert te[0] == (k == len(wp) - 1)
        assert r[0] > v.config.rewards.reached - 1.0


def test_progress_towards_the_waypoint_pays_and_away_costs() -> None:
    rewards = []
    for vx in (1.0, -1.0):
        v = gymnasium.make_vec("cufund/Waypoints-v0", num_envs=1, rewards={"reached": 0.0})
        v.reset(seed=0)
        _place(v, (-0.5, 0.0, 1.5), (vx, 0.0, 0.0))
        rewards.append(v.step(np.zeros((1, 4)))[1][0])
    # 1 m/s for 10 ms: about 1 cm of progress either way, worth progress * 0.01 each
    assert rewards[0] - rewards[1] > 2 * 10.0 * 0.009

"""The vector env against its single-env view, itself and the observation layout's definition: env i of a vector
seeded s equals a single env seeded s + i bit for bit (through autoresets), the same seed gives the same rollout,
the C++ observation equals cufund.control.policy_observation's bit for bit, and autoreset follows Gymnasium's
next-step convention (reset obs, reward 0, flags false, the action ignored)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import cufund.envs  # noqa: F401  (registers the tasks)
from cufund.control import policy_observation as po

IDS = ["cufund/Hover-v0", "cufund/Waypoints-v0", "cufund/Gates-v0"]
MODES = ["rotor_speeds", "thrust_rates", "velocity"]


def _actions(n_steps: int, n: int, seed: int = 7) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1, 1, (n_steps, n, 4)) * 0.6


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("mode", MODES)
def test_vector_env_i_equals_single_env_seeded_s_plus_i(env_id: str, mode: str) -> None:
    n, steps = 3, 250
    kw = {"action_mode": mode, "episode_s": 0.8}  # truncations as well as crashes within the run
    vec = gymnasium.make_vec(env_id, num_envs=n, **kw)
    singles = [gymnasium.make(env_id, disable_env_checker=True, **kw).unwrapped for _ in range(n)]
    acts = _actions(steps, n)
    obs, _ = vec.reset(seed=40)
    s_obs = [env.reset(seed=40 + i)[0] for i, env in enumerate(singles)]
    np.testing.assert_array_equal(obs, np.stack(s_obs))
    done = np.zeros(n, dtype=bool)
    ends = 0
    for k in range(steps):
        obs, rew, term, trunc, _ = vec.step(acts[k])
        for i, env in enumerate(singles):
            if done[i]:  # the vector's next-step autoreset is the single env's reset()
                o = env.reset()[0]
                r, te, tr = 0.0, False, False
            else:
                o, r, te, tr, _ = env.step(acts[k, i])
            assert np.array_equal(obs[i], o), (k, i)
            assert rew[i] == r and term[i] == te and trunc[i] == tr, (k, i)
        done = term | trunc
        ends += int(done.sum())
    assert ends > 0


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_same_rollout_and_another_seed_another(env_id: str) -> None:
    acts = _actions(200, 8)

    def rollout(seed: int) -> list[np.ndarray]:
        v = gymnasium.make_vec(env_id, num_envs=8, randomisation={"mass": [0.8, 1.2], "wind_mps": [0, 1]})
        out = [v.reset(seed=seed)[0]]
        for a in acts:
            o, r, te, tr, _ = v.step(a)
            out += [o, r, te, tr]
        return out

    a, b, c = rollout(3), rollout(3), rollout(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], c[0])


@pytest.mark.parametrize("env_id", IDS)
def test_observation_equals_the_layout_definition_bit_for_bit(env_id: str) -> None:
    v = gymnasium.make_vec(env_id, num_envs=16)
    cfg = v.config
    obs, _ = v.reset(seed=1)
    acts = _actions(60, 16)
    prev = np.zeros((16, 4))
    for k in range(60):
        if k:
            obs, _, te, tr, _ = v.step(acts[k])
            prev = np.clip(acts[k], -1, 1)
        b = v.batch
        K = len(cfg.targets)
        idx = np.minimum(v.target_index[:, None] + np.arange(cfg.n_ahead)[None, :], K - 1)
        tg = np.asarray(cfg.targets)
        normals = None
        if cfg.task == "gates":
            yaw = np.radians(tg[idx, 3])
            normals = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], axis=2)
        a_prev = np.where((v._core.episode_steps == 0)[:, None], 0.0, prev)
        want = po.build_observation(tg[idx, :3], b.p, b.v, b.q, b.w, a_prev, normals)
        np.testing.assert_array_equal(obs, want)
        assert obs.shape[1] == po.observation_size(cfg.n_ahead, cfg.target_dim)


def _crash_env(v: gymnasium.vector.VectorEnv, i: int) -> None:
    v.batch.p[i] = (0.0, 0.0, -5.0)  # far below the target and under crash_z: the next step terminates


def test_autoreset_next_step_semantics() -> None:
    n = 4
    envs = [gymnasium.make_vec("cufund/Hover-v0", num_envs=n) for _ in range(2)]
    outs = []
    for j, v in enumerate(envs):
        v.reset(seed=5)
        v.step(np.zeros((n, 4)))
        _crash_env(v, 2)
        o1, r1, te1, tr1, _ = v.step(np.zeros((n, 4)))
        assert te1[2] and not tr1[2] and r1[2] < -v.config.rewards.crash + v.config.rewards.alive
        assert not te1[[0, 1, 3]].any()
        # the step after: env 2 is reset (its action, different in the two copies, is ignored)
        a = np.zeros((n, 4))
        a[2] = (1.0, -1.0, 1.0, -1.0) if j else (-0.3, 0.2, 0.9, 0.0)
        o2, r2, te2, tr2, _ = v.step(a)
        assert r2[2] == 0.0 and not te2[2] and not tr2[2]
        assert v._core.episode_steps[2] == 0
        assert np.all(o2[2, -4:] == 0.0)  # no previous action after a reset
        assert np.linalg.norm(o2[2, :3]) < np.linalg.norm(v.config.spawn_extent) + 1e-6  # spawned near the target
        outs.append(o2)
    np.testing.assert_array_equal(outs[0][2], outs[1][2])


def test_truncation_after_episode_s() -> None:
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=2, action_mode="velocity", episode_s=0.05)
    v.reset(seed=0)
    flags = [v.step(np.zeros((2, 4)))[3].copy() for _ in range(6)]
    assert [f.all() for f in flags] == [False, False, False, False, True, False]


def test_bad_actions_name_the_field() -> None:
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=2)
    v.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must have shape \(2, 4\)"):
        v.step(np.zeros((3, 4)))
    with pytest.raises(ValueError, match="actions must be finite"):
        v.step(np.full((2, 4), np.nan))

"""Waypoints-v0 against hand-computed cases: reaching a waypoint pays the bonus and moves the observation's
target blocks on; the last one ends the episode (terminated, a success: no crash penalty); progress pays."""

from __future__ import annotations

import gymnasium
import numpy as np

import cufund.envs


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


# The timed reference (segment_s): the target moves from waypoint to waypoint on minimum-jerk segments.

_TIMED = {
    "segment_s": [1.0, 2.0],
    "hold_s": [0.2, 0.6],
    "waypoint_jitter_m": [0.3, 0.2, 0.1],
    "lookahead_s": 0.25,
    "n_ahead": 3,
}


def _min_jerk(a: np.ndarray, b: np.ndarray, T: float, s: float) -> np.ndarray:
    """p, v, acc (9,) at time s into a rest-to-rest quintic from a to b in T, its coefficients solved from the six
    boundary conditions (independent of the closed form the C++ uses)."""
    M = np.array(
        [
            [1, 0, 0, 0, 0, 0],
            [0, 1, 0, 0, 0, 0],
            [0, 0, 2, 0, 0, 0],
            [1, T, T**2, T**3, T**4, T**5],
            [0, 1, 2 * T, 3 * T**2, 4 * T**3, 5 * T**4],
            [0, 0, 2, 6 * T, 12 * T**2, 20 * T**3],
        ]
    )
    out = np.empty(9)
    for j in range(3):
        c = np.linalg.solve(M, [a[j], 0, 0, b[j], 0, 0])
        poly = np.polynomial.Polynomial(c)
        out[j], out[3 + j], out[6 + j] = poly(s), poly.deriv(1)(s), poly.deriv(2)(s)
    return out


def test_timed_reference_rests_then_follows_a_minimum_jerk_segment() -> None:
    v = gymnasium.make_vec("cufund/Waypoints-v0", num_envs=3, **_TIMED)
    v.reset(seed=4)
    for env in range(3):
        wp = v.waypoints(env)
        nominal = np.asarray(v.config.targets)
        assert np.all(np.abs(wp - nominal) <= np.asarray(_TIMED["waypoint_jitter_m"]) + 1e-12)
        assert np.any(wp != nominal)
        # the first waypoint is held from t = 0; find where the reference leaves it and arrives at the second
        ts = np.arange(0.0, 3.0, 1e-3)
        pos = np.array([v.reference(env, t)[:3] for t in ts])
        moving = np.linalg.norm(pos - wp[0], axis=1) > 0
        t_leave = ts[np.argmax(moving)] - 1e-3
        at_next = np.linalg.norm(pos - wp[1], axis=1) == 0
        t_arrive = ts[np.argmax(at_next)]
        assert 0.2 - 2e-3 <= t_leave <= 0.6 + 2e-3 and 1.0 - 2e-3 <= t_arrive - t_leave <= 2.0 + 2e-3
        T = t_arrive - t_leave
        for f in (0.1, 0.37, 0.5, 0.8):  # in the middle of the segment: the quintic, to the time grid's resolution
            got = v.reference(env, t_leave + f * T)
            want = _min_jerk(wp[0], wp[1], T, f * T)
            np.testing.assert_allclose(got, want, atol=0.02 * max(1.0, np.abs(want).max()))
        # long after the last segment: resting at the last waypoint
        np.testing.assert_array_equal(v.reference(env, 100.0), np.concatenate([wp[-1], np.zeros(6)]))


def test_timed_reference_observation_and_reward_by_hand() -> None:
    from cufund.control import policy_observation as po

    smooth = 0.3
    v = gymnasium.make_vec(
        "cufund/Waypoints-v0", num_envs=2, action_mode="thrust_rates", rewards={"smoothness": smooth}, **_TIMED
    )
    obs, _ = v.reset(seed=7)
    a_prev = np.zeros((2, 4))
    rng = np.random.default_rng(0)
    w = v.config.rewards
    for step in range(1, 150):
        a = rng.uniform(-0.05, 0.05, (2, 4))
        obs, r, te, tr, _ = v.step(a)
        assert not te.any() and not tr.any()
        b = v.batch
        for env in range(2):
            ref = v.reference(env, step * v.config.dt)
            tg = po.lookahead_targets(ref[:3], ref[3:6], ref[6:], 3, _TIMED["lookahead_s"])
            want_obs = po.build_observation(tg, b.p[env], b.v[env], b.q[env], b.w[env], a[env])
            np.testing.assert_array_equal(obs[env], want_obs)
            d = np.linalg.norm(ref[:3] - b.p[env])
            want = (
                w.alive
                - w.position * d
                - w.velocity * np.linalg.norm(b.v[env] - ref[3:6])
                - w.rate * np.linalg.norm(b.w[env])
                - w.action * np.sum(a[env] ** 2)
                - smooth * np.sum((a[env] - a_prev[env]) ** 2)
            )
            assert abs(r[env] - want) < 1e-9
        a_prev = a


def test_timed_reference_is_refused_where_it_means_nothing() -> None:
    import pytest

    from cufund.core.config import ConfigError

    with pytest.raises(ConfigError, match="segment_s"):
        gymnasium.make_vec("cufund/Hover-v0", num_envs=1, segment_s=[1.0, 2.0])
    with pytest.raises(ConfigError, match="segment_s"):
        gymnasium.make_vec("cufund/Waypoints-v0", num_envs=1, segment_s=[0.0, 2.0])
    with pytest.raises(ConfigError, match="waypoint_jitter_m"):
        gymnasium.make_vec("cufund/Waypoints-v0", num_envs=1, waypoint_jitter_m=[0.1, -0.1, 0.0])
    # the timed reference's other keys without segment_s would be ignored: refused, naming the key
    for key, value in (("lookahead_s", 0.2), ("hold_s", [0.5, 1.0]), ("waypoint_jitter_m", [0.0, 0.3, 0.0])):
        with pytest.raises(ConfigError, match=f"{key} is for a timed reference"):
            gymnasium.make_vec("cufund/Waypoints-v0", num_envs=1, **{key: value})


def test_the_shipped_waypoints_policy_tracks_its_timed_reference() -> None:
    """The policy square_policy flies (python/cufund/envs/policies/waypoints_cu_astro), run by onnxruntime on 20
    episodes of the task it was trained on (its train_config's env settings, the nominal vehicle): every one stays
    up for the whole episode and the RMS distance to the reference, from 1 s on, is below 5 cm. Fails when the
    observation, the reference or the action decoding drift from what the policy was trained on."""
    pytest = __import__("pytest")
    pytest.importorskip("onnxruntime")
    from pathlib import Path

    import yaml

    from cufund.envs.train import make_env, onnx_actor

    folder = Path(cufund.envs.__file__).parent / "policies" / "waypoints_cu_astro"
    cfg = yaml.safe_load((folder / "train_config.yaml").read_text())
    kwargs = dict(cfg["env_kwargs"], randomisation={})
    n = 20
    env = make_env(cfg["task"], n, kwargs)
    act = onnx_actor(folder / "policy.onnx")
    obs, _ = env.reset(seed=31)
    dt, steps = env.config.dt, env.config.max_steps
    err = np.zeros((steps - 1, n))
    for k in range(steps - 1):  # the last step truncates and the next would reset
        obs, _, term, trunc, _ = env.step(act(obs))
        assert not term.any() and not trunc.any()
        ref = np.array([env.reference(i, (k + 1) * dt)[:3] for i in range(n)])
        err[k] = np.linalg.norm(np.asarray(env.batch.p) - ref, axis=1)
    rms = np.sqrt(np.mean(err[int(1.0 / dt) :] ** 2))
    assert rms < 0.05, f"RMS distance to the reference {100 * rms:.1f} cm"

"""Hover-v0 against hand-computed cases: the reward formula on the state the step produced, crashes, and the
dynamics the env steps equal cufund's QuadrotorBatch fed the documented rotor-speed mapping, bit for bit."""

from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np

import cufund.envs  # noqa: F401
from cufund.vehicle import QuadrotorBatch, presets


def _hover_env(n: int = 4, **kw: object) -> gymnasium.vector.VectorEnv:
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=n, **kw)
    v.reset(seed=11)
    return v


def test_reward_is_the_documented_formula() -> None:
    v = _hover_env()
    w = v.config.rewards
    a = np.array([[0.1, -0.2, 0.3, 0.0], [0, 0, 0, 0], [1, 1, 1, 1], [-0.5, 0.5, -0.5, 0.5]])
    for _ in range(20):
        _, r, te, _, _ = v.step(a)
        b = v.batch
        e = np.linalg.norm(np.array([0.0, 0.0, 1.0]) - b.p, axis=1)
        want = (
            w.alive
            - w.position * e
            - w.velocity * np.linalg.norm(b.v, axis=1)
            - w.rate * np.linalg.norm(b.w, axis=1)
            - w.action * np.sum(a * a, axis=1)
            - w.crash * te
        )
        np.testing.assert_allclose(r, want, rtol=0, atol=1e-12)


def test_a_vehicle_at_the_target_at_rest_with_no_action_earns_alive() -> None:
    v = _hover_env(1)
    b = v.batch
    b.p[0] = (0.0, 0.0, 1.0)
    b.v[0] = 0
    b.w[0] = 0
    b.q[0] = (1, 0, 0, 0)
    b.rotor_speeds[0] = np.sqrt(0.03 * 9.80665 / (4 * 2.3e-08))
    _, r, te, tr, _ = v.step(np.zeros((1, 4)))
    # one step of hover: it stays within a micrometre, so the reward is alive minus almost nothing
    assert not te[0] and not tr[0]
    assert abs(r[0] - 1.0) < 1e-4


def test_crashes_terminate_with_the_penalty() -> None:
    v = _hover_env(3)
    b = v.batch
    b.p[0] = (0.0, 0.0, 1.0 + 2.5)  # beyond bound_m = 2 from the target
    b.p[1] = (0.0, 0.0, 0.01)  # below crash_z = 0.02
    b.p[2] = (0.0, 0.0, 1.0)
    b.v[:] = 0
    _, r, te, _, _ = v.step(np.zeros((3, 4)))
    assert te.tolist() == [True, True, False]
    assert r[0] < 1.0 - 2.5 - 10.0 + 0.1 and r[1] < 1.0 - 0.99 - 10.0 + 0.1


def test_dynamics_equal_quadrotor_batch_with_the_rotor_speed_mapping() -> None:
    v = _hover_env(5)
    params = presets.crazyflie()
    ref = QuadrotorBatch(dataclasses.replace(params, max_integration_step=0.01), 5)
    b = v.batch
    for name in ("p", "v", "q", "w", "rotor_speeds"):
        getattr(ref, name)[:] = getattr(b, name)
    hover = np.sqrt(params.mass * params.gravity / (4 * params.k_f))
    span = min(params.rotor_speed_max - hover, hover - params.rotor_speed_min)
    acts = np.random.default_rng(0).uniform(-0.3, 0.3, (30, 5, 4))
    for a in acts:
        v.step(a)
        ref.step(0.01, hover + a * span)
        for name in ("p", "v", "q", "w", "rotor_speeds"):
            np.testing.assert_array_equal(getattr(b, name), getattr(ref, name))

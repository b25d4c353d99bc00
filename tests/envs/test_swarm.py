"""SwarmGates-v0 (PettingZoo ParallelEnv): the API test, the agents' state, vehicle-vehicle collisions, and each
agent's depth seeing the others (not itself, and no longer once they left)."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from cufund.control import policy_observation as po
from cufund.core.config import ConfigError
from cufund.envs import swarm_gates_v0
from cufund.envs.vector_env import CufundVectorEnv

ZERO = np.zeros(4, dtype=np.float32)


def _place(env: swarm_gates_v0.SwarmGatesEnv, positions: list[list[float]]) -> None:
    b = env.vector.batch
    for i, p in enumerate(positions):
        b.p[i] = p
        b.v[i] = 0.0
        b.w[i] = 0.0
        b.q[i] = [1.0, 0.0, 0.0, 0.0]  # level, facing +x


def test_parallel_api() -> None:
    parallel_api_test(swarm_gates_v0.parallel_env(num_agents=3), num_cycles=100)


def test_lidar_observation_and_bad_arguments() -> None:
    env = swarm_gates_v0.parallel_env(num_agents=2, sensor="lidar", sensor_params={"pattern": "vlp16", "stride": 90})
    obs, _ = env.reset(seed=0)
    assert obs["drone_0"]["lidar"].shape == env.observation_space("drone_0")["lidar"].shape == (320,)
    with pytest.raises(ConfigError, match="num_agents"):
        swarm_gates_v0.parallel_env(num_agents=0)
    with pytest.raises(ConfigError, match="collision_radius"):
        swarm_gates_v0.parallel_env(collision_radius=-1.0)


def test_state_at_reset_is_the_gates_task_observation() -> None:
    # with (numerically) no spacing the rebuilt observation must be the C++ task's own, bit for bit
    env = swarm_gates_v0.parallel_env(num_agents=3, spacing=1e-300)
    obs, _ = env.reset(seed=4)
    ref, _ = CufundVectorEnv(3, "swarm_gates").reset(seed=4)
    for i in range(3):
        np.testing.assert_array_equal(obs[f"drone_{i}"]["state"], ref[i])
    # and spread out: the agents stand spacing apart across the first gate's normal (+x)
    env = swarm_gates_v0.parallel_env(num_agents=3, spacing=0.5)
    env.reset(seed=4)
    np.testing.assert_allclose(np.diff(np.asarray(env.vector.batch.p)[:, 1]), 0.5, atol=0.11)


def test_two_agents_that_touch_are_terminated_and_leave() -> None:
    env = swarm_gates_v0.parallel_env(num_agents=3, collision_radius=0.1)
    env.reset(seed=0)
    _place(env, [[0.0, -1.5, 1.0], [0.15, -1.5, 1.0], [0.0, 1.5, 1.0]])  # 0.15 m apart: spheres overlap
    obs, rew, term, trunc, info = env.step(dict.fromkeys(env.agents, ZERO))
    assert term == {"drone_0": True, "drone_1": True, "drone_2": False}
    assert info["drone_0"]["vehicle_collision"] and not info["drone_2"]["vehicle_collision"]
    assert rew["drone_0"] < rew["drone_2"] - 0.9 * env.config.rewards.crash
    assert env.agents == ["drone_2"]
    obs, rew, term, trunc, info = env.step({"drone_2": ZERO})
    assert set(obs) == {"drone_2"} and not term["drone_2"]


def test_an_agent_depth_sees_the_other_vehicle_not_itself() -> None:
    env = swarm_gates_v0.parallel_env(num_agents=3, box_half_extents=(0.1, 0.1, 0.04))
    env.reset(seed=0)
    # drone_1 1 m ahead of drone_0 (both facing +x), drone_2 off to the side
    _place(env, [[0.0, -1.5, 1.0], [1.0, -1.5, 1.0], [0.0, 1.5, 1.0]])
    obs, _, term, _, _ = env.step(dict.fromkeys(env.agents, ZERO))
    assert not any(term.values())
    p = np.asarray(env.vector.batch.p)
    centre0 = obs["drone_0"]["depth"][0, 15:17, 15:17]
    # the centre pixels meet drone_1's rear face: its centre's x minus the half extent (both still level)
    np.testing.assert_allclose(centre0, p[1, 0] - p[0, 0] - 0.1, atol=0.01)
    # drone_1 looks away from drone_0, and never sees its own box: open air straight ahead
    assert np.all(obs["drone_1"]["depth"][0, 15:17, 15:17] == 10.0)
    # once drone_1 has left (it touches drone_2), drone_0 no longer sees it
    _place(env, [[0.0, -1.5, 1.0], [1.0, -1.5, 1.0], [1.1, -1.5, 1.0]])
    env.step(dict.fromkeys(env.agents, ZERO))
    assert env.agents == ["drone_0"]
    obs, _, _, _, _ = env.step({"drone_0": ZERO})
    assert np.all(obs["drone_0"]["depth"][0, 15:17, 15:17] == 10.0)


def test_reset_observation_keeps_the_configured_noise() -> None:
    # spreading the agents moves their targets, not their noise: the gyro's and the position noise are in the
    # first observation as in every later one
    env = swarm_gates_v0.parallel_env(num_agents=3, imu_noise=True, randomisation={"position_noise_m": [0.05, 0.05]})
    obs, _ = env.reset(seed=1)
    b = env.vector.batch
    cfg = env.config
    sl = po.slices(cfg.n_ahead, cfg.target_dim)
    state = np.stack([obs[f"drone_{i}"]["state"] for i in range(3)]).astype(np.float64)
    assert np.all(state[:, sl["w_B"]] != np.asarray(b.w, dtype=np.float32))
    rel = np.asarray(cfg.targets[0][:3]) - np.asarray(b.p)
    err = state[:, :3] - rel
    assert np.all(np.abs(err) > 1e-6) and np.all(np.abs(err) < 0.05 * 6)

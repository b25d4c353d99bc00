"""ForestAvoid-v0: registration, check_env, the sensor observation, collisions with the world's meshes, the goal,
next-step autoreset after them, and seeded rollouts."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cufund.envs  # noqa: F401  (registers the tasks)
from cufund.envs.forest_avoid import ForestAvoidEnv, ForestAvoidSingleEnv, WorldCollisions
from cufund.envs.observation_sensors import BatchRangeSensor, DepthCameraSpec
from cufund.worlds import World


def _trunk(env: ForestAvoidEnv) -> tuple[np.ndarray, float]:
    """Centre (x, y) and radius of the forest's first trunk, read from its mesh."""
    v = next(o for o in env.world.objects if o.label == "tree").vertices
    c = v[:, :2].mean(0)
    return c, float(np.max(np.linalg.norm(v[:, :2] - c, axis=1)))


def test_registered_with_both_entry_points() -> None:
    vec = gymnasium.make_vec("cufund/ForestAvoid-v0", num_envs=3)
    assert isinstance(vec, ForestAvoidEnv) and vec.num_envs == 3
    assert vec.single_observation_space["depth"].shape == (1, 64, 64)
    single = gymnasium.make("cufund/ForestAvoid-v0", sensor="lidar", sensor_params={"pattern": "mid360"})
    assert isinstance(single.unwrapped, ForestAvoidSingleEnv)
    assert single.observation_space["lidar"].shape == (1000,)


@pytest.mark.parametrize("sensor", ["depth", "lidar"])
def test_check_env(sensor: str) -> None:
    check_env(ForestAvoidSingleEnv(sensor=sensor), skip_render_check=True)


def test_observation_is_the_batched_cast_at_the_vehicles_poses() -> None:
    env = ForestAvoidEnv(4, sensor_params={"width": 32, "height": 24, "fov_deg": 80.0})
    obs, _ = env.reset(seed=3)
    assert obs["depth"].shape == (4, 1, 24, 32) and obs["depth"].dtype == np.float32
    b = env.batch
    ref = BatchRangeSensor(env.world.raycast_scene, DepthCameraSpec(width=32, height=24, fov_deg=80.0))
    # The forest's depth is cast analytically (test_depth_prism.py): Embree's within float rounding.
    np.testing.assert_allclose(obs["depth"][:, 0], ref.observe(np.asarray(b.p), np.asarray(b.q)), rtol=0, atol=1e-4)
    assert obs["depth"].max() <= 20.0 and obs["depth"].min() > 0.0
    # spawned around the start, west of the forest, the goal ahead in the state
    np.testing.assert_allclose(np.asarray(b.p).mean(0), [-11.5, 0.0, 1.5], atol=3.0)


def test_same_seed_same_rollout() -> None:
    def roll(seed: int) -> list[np.ndarray]:
        env = ForestAvoidEnv(3, sensor_params={"width": 16, "height": 16, "range_noise_std": 0.05})
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(0)
        out = [obs["depth"].copy(), obs["state"].copy()]
        for _ in range(20):
            obs, r, te, tr, _ = env.step(rng.uniform(-1, 1, (3, 4)))
            out += [obs["depth"].copy(), obs["state"].copy(), r.copy()]
        return out

    a, b, c = roll(5), roll(5), roll(6)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_env_i_of_a_vector_is_a_single_env_seeded_seed_plus_i() -> None:
    kw = {"sensor_params": {"width": 16, "height": 16, "range_noise_std": 0.05, "dropout": 0.1}}
    vec = ForestAvoidEnv(3, **kw)
    single = ForestAvoidSingleEnv(**kw)
    obs_v, _ = vec.reset(seed=5)
    obs_s, _ = single.reset(seed=7)
    rng = np.random.default_rng(1)
    for _ in range(10):
        for key in ("state", "depth"):
            np.testing.assert_array_equal(obs_v[key][2], obs_s[key])
        a = rng.uniform(-1, 1, (3, 4))
        obs_v, *_ = vec.step(a)
        obs_s, *_ = single.step(a[2])


def test_a_trunk_ends_the_episode_with_the_crash_penalty_then_autoreset() -> None:
    env = ForestAvoidEnv(2, vehicle_radius=0.1)
    env.reset(seed=0)
    (cx, cy), rt = _trunk(env)
    zero = np.zeros((2, 4))
    _, r_clear, _, _, _ = env.step(zero)  # the reward of a clear step, for comparison
    env.batch.p[0] = [cx + rt + 0.05, cy, 1.0]  # the sphere (0.1 m) overlaps the trunk
    env.batch.v[0] = 0.0
    _, r, term, trunc, _ = env.step(zero)
    assert term[0] and not trunc[0] and not term[1]
    assert r[0] < r_clear[0] - 0.9 * env.config.rewards.crash
    obs, r, term, trunc, _ = env.step(zero)  # next-step autoreset: back at the start, reward 0
    assert r[0] == 0.0 and not term[0] and not trunc[0]
    assert np.linalg.norm(np.asarray(env.batch.p)[0] - [-11.5, 0.0, 1.5]) < 3.5


def test_reaching_the_goal_ends_the_episode_with_the_bonus() -> None:
    env = ForestAvoidEnv(1)
    env.reset(seed=0)
    env.batch.p[0] = [11.5, 0.1, 1.5]
    env.batch.v[0] = 0.0
    _, r, term, _, _ = env.step(np.zeros((1, 4)))
    assert term[0] and r[0] > 0.9 * env.config.rewards.reached


def test_world_collisions_are_the_sphere_against_the_meshes() -> None:
    world = World()
    world.add_box((1.0, 2.0, 3.0), (0.0, 0.0, 1.5))
    coll = WorldCollisions(world, radius=0.2)
    q = np.tile([1.0, 0, 0, 0], (6, 1))
    p = np.array(
        [
            [0.69, 0.0, 1.0],  # 0.19 from the +x face: touches
            [0.71, 0.0, 1.0],  # 0.21: clear
            [0.0, 1.19, 2.0],  # 0.19 from the +y face
            [0.5 + 0.14, 1.0 + 0.14, 1.0],  # 0.198 from the edge: touches
            [0.5 + 0.15, 1.0 + 0.15, 1.0],  # 0.212 from the edge: clear
            [5.0, 5.0, 1.0],  # far
        ]
    )
    np.testing.assert_array_equal(coll(p, q), [True, False, True, True, False, False])

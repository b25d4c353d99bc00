"""``import cufund.envs`` registers the state-only tasks: make gives cufund's single env (passing Gymnasium's
check_env), make_vec cufund's own VectorEnv (not Gymnasium's sync wrapper); kwargs override the task's YAML."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import cufund.envs
from cufund.core.config import ConfigError

IDS = ["cufund/Hover-v0", "cufund/Waypoints-v0", "cufund/Gates-v0"]


@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_is_cufunds_own_vector_env(env_id: str) -> None:
    v = gymnasium.make_vec(env_id, num_envs=3)
    assert isinstance(v, cufund.envs.CufundVectorEnv)
    assert v.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, _ = v.reset(seed=0)
    assert obs.shape == (3, v.single_observation_space.shape[0]) and obs.dtype == np.float32
    assert v.observation_space.contains(obs)


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("mode", ["rotor_speeds", "thrust_rates", "velocity"])
def test_single_env_passes_check_env(env_id: str, mode: str) -> None:
    env = gymnasium.make(env_id, action_mode=mode, disable_env_checker=True)
    assert isinstance(env.unwrapped, cufund.envs.CufundEnv)
    check_env(env.unwrapped, skip_render_check=True)


def test_kwargs_override_the_yaml_and_bad_ones_name_the_field() -> None:
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=2, action_mode="thrust_rates", episode_s=1.0)
    assert v.config.action_mode == "thrust_rates" and v.config.max_steps == 100
    with pytest.raises(ConfigError, match="action_mode must be one of"):
        gymnasium.make_vec("cufund/Hover-v0", num_envs=2, action_mode="rpm")
    with pytest.raises(ConfigError, match="randomisation.mass must be a range"):
        gymnasium.make_vec("cufund/Hover-v0", num_envs=2, randomisation={"mass": 3})
    with pytest.raises(ConfigError, match="unknown key 'colour'"):
        gymnasium.make_vec("cufund/Hover-v0", num_envs=2, colour="red")

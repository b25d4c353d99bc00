"""A single cufund env (``gymnasium.make("cufund/Hover-v0")``): a vector env of one, without its autoreset."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from .config import TaskConfig
from .vector_env import CufundVectorEnv

__all__ = ["CufundEnv"]


class CufundEnv(gymnasium.Env):
    """One vehicle of a task: the same numbers as env 0 of a :class:`CufundVectorEnv` seeded alike (and env ``i``
    of a vector seeded ``s`` equals a single env seeded ``s + i``). After ``terminated`` or ``truncated`` call
    ``reset()``, as for any Gymnasium env."""

    metadata = {"render_modes": []}

    def __init__(self, task: str | TaskConfig = "hover", render_mode: str | None = None, **overrides: Any) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (cufund envs do not render), got {render_mode!r}")
        self.vector = CufundVectorEnv(1, task, **overrides)
        self.config = self.vector.config
        self.observation_space = self.vector.single_observation_space
        self.action_space = self.vector.single_action_space
        self.render_mode = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        obs, info = self.vector.reset(seed=seed, options=options)
        return obs[0], info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, rew, term, trunc, info = self.vector.step(np.asarray(action, dtype=np.float64).reshape(1, -1))
        return obs[0], float(rew[0]), bool(term[0]), bool(trunc[0]), info

    def close(self) -> None:
        self.vector.close()

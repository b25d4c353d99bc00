"""Registration of cufund's tasks with Gymnasium (called by ``import cufund.envs``; idempotent)."""

from __future__ import annotations

import gymnasium

__all__ = ["STATE_TASKS", "register_envs"]

STATE_TASKS = {"cufund/Hover-v0": "hover", "cufund/Waypoints-v0": "waypoints", "cufund/Gates-v0": "gates"}
"""The state-only tasks: Gymnasium id -> task YAML (python/cufund/envs/tasks/)."""


def register_envs() -> None:
    """Registers every state-only task: ``entry_point`` the single env, ``vector_entry_point`` cufund's VectorEnv."""
    for env_id, task in STATE_TASKS.items():
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(
            id=env_id,
            entry_point="cufund.envs.single_env:CufundEnv",
            vector_entry_point="cufund.envs.vector_env:CufundVectorEnv",
            kwargs={"task": task},
            disable_env_checker=False,
        )
    if "cufund/ForestAvoid-v0" not in gymnasium.registry:  # a sensor task: its own envs (cufund.envs.forest_avoid)
        gymnasium.register(
            id="cufund/ForestAvoid-v0",
            entry_point="cufund.envs.forest_avoid:ForestAvoidSingleEnv",
            vector_entry_point="cufund.envs.forest_avoid:ForestAvoidEnv",
            disable_env_checker=False,
        )

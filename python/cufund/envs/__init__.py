"""Learning environments on the C++ batch (Gymnasium >= 1.0).

``import cufund.envs`` registers ``cufund/Hover-v0``, ``cufund/Waypoints-v0`` and ``cufund/Gates-v0`` (and the
sensor tasks of this package) with Gymnasium: ``gymnasium.make(...)`` gives a single env
(:class:`~cufund.envs.single_env.CufundEnv`), ``gymnasium.make_vec(..., num_envs=N)`` cufund's own batched
:class:`~cufund.envs.vector_env.CufundVectorEnv` (not Gymnasium's sync wrapper). Keyword arguments override the
task's YAML (python/cufund/envs/tasks/*.yaml), e.g. ``action_mode="thrust_rates"``. See docs/guides/learning.md.
"""

from __future__ import annotations

from .config import ACTION_MODES, TASKS, Randomisation, Rewards, TaskConfig, load_task
from .registration import register_envs
from .single_env import CufundEnv
from .vector_env import CufundVectorEnv, GatesEnv, HoverEnv, WaypointsEnv

__all__ = [
    "ACTION_MODES",
    "TASKS",
    "CufundEnv",
    "CufundVectorEnv",
    "GatesEnv",
    "HoverEnv",
    "Randomisation",
    "Rewards",
    "TaskConfig",
    "WaypointsEnv",
    "load_task",
    "register_envs",
]

register_envs()

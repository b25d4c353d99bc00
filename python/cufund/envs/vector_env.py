"""cufund's own Gymnasium VectorEnv over one QuadrotorBatch: every env is one vehicle of the batch.

Gymnasium >= 1.0 next-step autoreset (``metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP``): the step after
an env terminated or was truncated resets it and returns its first observation with reward 0, terminated and
truncated False; the action given for it in that step is ignored. One ``seed`` derives every stream: env ``i``
draws its resets (and its randomisation and noise) from stream ``seed + i``, as Gymnasium's SyncVectorEnv seeds
its envs, so env ``i`` of a vector equals a single env seeded ``seed + i`` bit for bit.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from cufund.control import policy_observation as po
from cufund.vehicle import QuadrotorBatch, presets

from .config import TaskConfig, load_task

__all__ = ["OBS_BOUND", "CufundVectorEnv", "GatesEnv", "HoverEnv", "WaypointsEnv", "make_config"]

OBS_BOUND = 1.0e4
"""Bound of the observation space per entry."""


def make_config(task: str | TaskConfig, overrides: dict[str, Any]) -> TaskConfig:
    """The task's configuration with keyword overrides (``gymnasium.make`` kwargs)."""
    if isinstance(task, TaskConfig):
        return task.replace(**overrides) if overrides else task
    return load_task(task, **overrides)


class CufundVectorEnv(VectorEnv):
    """``num_envs`` vehicles of one task (see :class:`HoverEnv`, :class:`WaypointsEnv`, :class:`GatesEnv` for each
    task's observation, reward and termination). Actions (num_envs, 4) in [-1, 1]; observations (num_envs, D)
    float32 in the layout of :mod:`cufund.control.policy_observation`."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
    task_name = "hover"

    def __init__(self, num_envs: int = 1, task: str | TaskConfig | None = None, **overrides: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.config = cfg = make_config(task if task is not None else self.task_name, overrides)
        self.num_envs = int(num_envs)
        params = getattr(presets, cfg.vehicle)()
        self.params = dataclasses.replace(params, max_integration_step=cfg.dt / cfg.substeps)
        self.batch = QuadrotorBatch(self.params, self.num_envs)
        self.obs_size = po.observation_size(cfg.n_ahead, cfg.target_dim)
        # finite bounds (check_env warns on infinite ones); a vehicle this far off was terminated long before
        self.single_observation_space = gymnasium.spaces.Box(-OBS_BOUND, OBS_BOUND, (self.obs_size,), np.float32)
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, (po.ACTION_SIZE,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._seed: int | None = None
        self._rngs = [np.random.default_rng(i) for i in range(self.num_envs)]
        self._a_prev = np.zeros((self.num_envs, 4))
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._done = np.zeros(self.num_envs, dtype=bool)
        self._omega_hover = float(np.sqrt(params.mass * params.gravity / (4 * params.k_f)))

    # --- the numpy path (Hover-v0, rotor speeds), to be replaced by cpp/envs -------------------------------------
    def _target(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.config.targets[0][:3]), (self.num_envs, 3))

    def _reset_envs(self, mask: np.ndarray) -> None:
        cfg = self.config
        b = self.batch
        for i in np.flatnonzero(mask):
            rng = self._rngs[i]
            p0 = np.asarray(cfg.targets[0][:3]) + rng.uniform(-1, 1, 3) * np.asarray(cfg.spawn_extent)
            b.p[i] = p0
            b.v[i] = rng.uniform(-1, 1, 3) * cfg.spawn_speed
            tilt = np.radians(cfg.spawn_tilt_deg)
            roll, pitch = rng.uniform(-tilt, tilt, 2)
            yaw = rng.uniform(-np.pi, np.pi)
            cr, sr, cp, sp, cy, sy = (
                np.cos(roll / 2),
                np.sin(roll / 2),
                np.cos(pitch / 2),
                np.sin(pitch / 2),
                np.cos(yaw / 2),
                np.sin(yaw / 2),
            )
            b.q[i] = (
                cr * cp * cy + sr * sp * sy,
                sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy,
                cr * cp * sy - sr * sp * cy,
            )
            b.w[i] = rng.uniform(-1, 1, 3) * cfg.spawn_rate
            b.rotor_speeds[i] = self._omega_hover
            self._a_prev[i] = 0.0
            self._steps[i] = 0

    def _observe(self) -> np.ndarray:
        b = self.batch
        return po.build_observation(self._target()[:, None, :], b.p, b.v, b.q, b.w, self._a_prev)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        if seed is not None:
            self._seed = int(seed)
            self._rngs = [np.random.default_rng(self._seed + i) for i in range(self.num_envs)]
        self.batch.reset()
        self._reset_envs(np.ones(self.num_envs, dtype=bool))
        self._done[:] = False
        return self._observe(), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        a = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, 4)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions must be finite numbers in [-1, 1], got a NaN or inf")
        a = np.clip(a, -1.0, 1.0)
        cfg = self.config
        p = self.params
        span = min(p.rotor_speed_max - self._omega_hover, self._omega_hover - p.rotor_speed_min)
        cmd = self._omega_hover + a * span
        self.batch.step(cfg.dt, cmd)
        self._a_prev[:] = a
        self._steps += 1
        b = self.batch
        e = np.linalg.norm(self._target() - b.p, axis=1)
        crash = (e > cfg.bound_m) | (b.p[:, 2] < cfg.crash_z)
        r = cfg.rewards
        rew = (
            r.alive
            - r.position * e
            - r.velocity * np.linalg.norm(b.v, axis=1)
            - r.rate * np.linalg.norm(b.w, axis=1)
            - r.action * np.sum(a * a, axis=1)
            - r.crash * crash
        )
        term = crash
        trunc = (self._steps >= cfg.max_steps) & ~term
        was_done = self._done.copy()
        if was_done.any():
            self._reset_envs(was_done)
            rew[was_done] = 0.0
            term[was_done] = False
            trunc[was_done] = False
        self._done = term | trunc
        return self._observe(), rew.astype(np.float64), term, trunc, {}


class HoverEnv(CufundVectorEnv):
    """Hover-v0: hold the point ``targets[0]``."""

    task_name = "hover"


class WaypointsEnv(CufundVectorEnv):
    """Waypoints-v0: fly through ``targets`` in order."""

    task_name = "waypoints"


class GatesEnv(CufundVectorEnv):
    """Gates-v0: pass through the gates in order."""

    task_name = "gates"

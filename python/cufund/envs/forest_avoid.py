"""ForestAvoid-v0: fly through a seeded random forest to a goal, seeing it with a depth camera or a LiDAR.

The task (python/cufund/envs/tasks/forest_avoid.yaml) is the C++ batch's hover task towards the goal
``targets[0]`` from a spawn box around ``start``: its reward ``alive - position |p - goal| - velocity |v| - rate |w|
- action |a|^2``, its crash (farther than ``bound_m`` from the goal, below ``crash_z``) and its truncation, plus

- **collision** with a trunk: the vehicle a sphere of ``vehicle_radius`` against the world's meshes (Bullet,
  :class:`cufund.worlds.collision.CollisionChecker`; the ground is the task's ``crash_z``) terminates the episode,
  reward ``- crash``;
- **goal**: within ``reach_radius`` of it terminates the episode, reward ``+ reached``.

Observation: a dict of ``state`` (the :mod:`cufund.control.policy_observation` layout) and ``depth`` (1, H, W)
(a :class:`~cufund.envs.observation_sensors.DepthCameraSpec`, 64 x 64 by default; cast by the exact analytic
prism caster, the forest being trunks on a ground quad) or ``lidar`` (R,) ranges (a
:class:`~cufund.envs.observation_sensors.LidarSpec`; Embree), cast for every env in one C++ call; a miss reads the
sensor's range_max. Every env flies in the same forest (``forest`` = :class:`ForestParams`), which stays put
across resets; the sensor noise, off by default, is seeded by the reset seed.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector.utils import batch_space

from cufund import _core
from cufund.core.config import ConfigError, from_dict
from cufund.worlds.builtin import forest
from cufund.worlds.collision import CollisionChecker
from cufund.worlds.world import World

from .config import TaskConfig
from .observation_sensors import BatchRangeSensor, DepthCameraSpec, LidarSpec, SensorSpec, prism_scene, sensor_spec
from .vector_env import CufundVectorEnv, task_params

__all__ = ["ForestAvoidEnv", "ForestAvoidSingleEnv", "ForestParams", "WorldCollisions"]


@dataclasses.dataclass(frozen=True)
class ForestParams:
    """The forest (:func:`cufund.worlds.builtin.forest`): trunks in a ``size`` square centred on the origin."""

    seed: int = 0
    n_trees: int = 80
    size: float = 20.0
    """[m]; the task's start and goal lie 1.5 m outside its west and east edges."""
    clearing: float = 1.0
    """No trunk within this of the origin [m]."""

    def build(self) -> World:
        return forest(self.seed, self.n_trees, self.size, self.clearing)


class WorldCollisions:
    """Which of N vehicles (spheres of ``radius``) touch a world's meshes: Bullet on those whose sphere overlaps an
    object's bounding box (a vectorised test first: most vehicles are clear of every trunk)."""

    def __init__(self, world: World, radius: float, ignore_labels: tuple[str, ...] = ("ground",)) -> None:
        if not (isinstance(radius, (int, float)) and np.isfinite(radius) and radius > 0):
            raise ConfigError(f"vehicle_radius must be a finite number > 0 [m], got {radius!r}")
        self.radius = float(radius)
        self.checker = CollisionChecker(world, radius=self.radius, ignore_labels=ignore_labels)
        boxes = [(o.vertices.min(0), o.vertices.max(0)) for o in world.objects if o.label not in ignore_labels]
        self.lo = np.array([b[0] for b in boxes]).reshape(-1, 3) - self.radius
        self.hi = np.array([b[1] for b in boxes]).reshape(-1, 3) + self.radius

    def __call__(self, p_W: np.ndarray, q_WB: np.ndarray) -> np.ndarray:
        """(N,) bool: vehicle i at (p_W[i], q_WB[i]) touches an object."""
        p = np.asarray(p_W, dtype=np.float64)
        out = np.zeros(len(p), dtype=bool)
        if len(self.lo) == 0:
            return out
        near = np.any(np.all((p[:, None, :] >= self.lo) & (p[:, None, :] <= self.hi), axis=2), axis=1)
        for i in np.flatnonzero(near):
            out[i] = self.checker.check(p[i], q_WB[i]) is not None
        return out


class ForestAvoidEnv(CufundVectorEnv):
    """``num_envs`` vehicles in one forest (see the module's docstring). ``sensor``: ``depth`` or ``lidar`` (or a
    spec); ``sensor_params``: the spec's fields (e.g. ``{"width": 32, "height": 32}``, ``{"pattern": "vlp16"}``);
    ``forest``: :class:`ForestParams` fields; other keywords override the task YAML."""

    task_name = "forest_avoid"

    def __init__(
        self,
        num_envs: int = 1,
        task: str | TaskConfig | None = None,
        *,
        sensor: str | SensorSpec = "depth",
        sensor_params: dict[str, Any] | None = None,
        forest: dict[str, Any] | ForestParams | None = None,
        vehicle_radius: float = 0.1,
        nthreads: int = 0,
        **overrides: Any,
    ) -> None:
        super().__init__(num_envs, task, **overrides)
        cfg = self.config
        if cfg.start is not None:  # the C++ hover task spawns around targets[0]: around start instead
            tp = task_params(cfg)
            tp.spawn_center = list(cfg.start)
            self._core = _core.envs.EnvBatch(self.params.to_core(), tp, self.num_envs)
        fp = forest if isinstance(forest, ForestParams) else from_dict(ForestParams, dict(forest or {}), "forest")
        self.forest = fp
        self.world = fp.build()
        if isinstance(sensor, (DepthCameraSpec, LidarSpec)):
            spec: SensorSpec = sensor
        elif isinstance(sensor, str):
            spec = sensor_spec(sensor, **(sensor_params or {}))
        else:
            raise ConfigError(f"sensor must be 'depth', 'lidar' or a sensor spec, got {sensor!r}")
        self.sensor_key = "depth" if isinstance(spec, DepthCameraSpec) else "lidar"
        # The forest is trunks (capped n-gon prisms) on a ground quad: a depth camera is cast analytically.
        prisms = prism_scene(self.world) if self.sensor_key == "depth" else None
        self.sensor = BatchRangeSensor(self.world.raycast_scene, spec, nthreads=nthreads, prisms=prisms)
        self.collisions = WorldCollisions(self.world, vehicle_radius)
        shape = (1, *spec.shape) if self.sensor_key == "depth" else spec.shape
        self.single_observation_space = gymnasium.spaces.Dict(
            {
                "state": self.single_observation_space,
                self.sensor_key: gymnasium.spaces.Box(0.0, spec.range_max, shape, np.float32),
            }
        )
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._goal = np.asarray(cfg.targets[0][:3])
        self._frame = 0

    def _with_sensor(self, state: np.ndarray) -> dict[str, np.ndarray]:
        b = self.batch
        img = self.sensor.observe(np.asarray(b.p), np.asarray(b.q), frame=self._frame)
        self._frame += 1
        if self.sensor_key == "depth":
            img = img[:, None]
        return {"state": state, self.sensor_key: img}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        state, info = super().reset(seed=seed, options=options)
        if seed is not None:
            self.sensor.seed = int(seed)
            self._frame = 0
        return self._with_sensor(state), info

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict]:
        state, rew, term, trunc, info = super().step(actions)
        b = self.batch
        p, q = np.asarray(b.p), np.asarray(b.q)
        fresh = self._core.episode_steps == 0  # reset by this step: their flags are False and reward 0
        hit = self.collisions(p, q) & ~fresh & ~term
        reached = (np.linalg.norm(p - self._goal, axis=1) < self.config.reach_radius) & ~fresh & ~term & ~hit
        r = self.config.rewards
        rew = rew - r.crash * hit + r.reached * reached
        extra = hit | reached
        if extra.any():
            self._core.end_episodes(extra)
        term = term | extra
        trunc = trunc & ~term
        return self._with_sensor(state), rew, term, trunc, info


class ForestAvoidSingleEnv(gymnasium.Env):
    """One ForestAvoid-v0 vehicle (``gymnasium.make("cufund/ForestAvoid-v0")``): env 0 of a
    :class:`ForestAvoidEnv` of one, without its autoreset (call ``reset()`` after the episode ends)."""

    metadata = {"render_modes": []}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (cufund envs do not render), got {render_mode!r}")
        kwargs.pop("task", None)
        self.vector = ForestAvoidEnv(1, **kwargs)
        self.config = self.vector.config
        self.observation_space = self.vector.single_observation_space
        self.action_space = self.vector.single_action_space
        self.render_mode = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        super().reset(seed=seed)
        obs, info = self.vector.reset(seed=seed, options=options)
        return {k: v[0] for k, v in obs.items()}, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        obs, rew, term, trunc, info = self.vector.step(np.asarray(action, dtype=np.float64).reshape(1, -1))
        return {k: v[0] for k, v in obs.items()}, float(rew[0]), bool(term[0]), bool(trunc[0]), info

    def close(self) -> None:
        self.vector.close()

"""``cufund/SwarmGates-v0``: a PettingZoo ``ParallelEnv`` of several vehicles passing gates in one world.

``parallel_env(num_agents=3, ...)`` gives agents ``drone_0``, ``drone_1``, ...; each is one env of the C++ gates
task (python/cufund/envs/tasks/swarm_gates.yaml: its reward, gate crossing, crash and truncation, the state in the
:mod:`cufund.control.policy_observation` layout), all in one world holding the gates' frames. On top of the task:

- **vehicle-vehicle collisions**: two agents collide when their spheres of ``collision_radius`` overlap (centres
  closer than 2 ``collision_radius``); both are terminated with the task's crash penalty.
- **each agent sees the others**: its depth camera (or LiDAR) is cast, for every agent in one C++ call, into the
  gates and the other agents' boxes (``box_half_extents`` about each body origin, along the body axes; its own is
  left out). An agent that is done leaves the world: the others neither see it nor collide with it.

The agents start in a row across the start (``spacing`` apart, perpendicular to the first gate's normal).
Observations: ``{"state": (D,), "depth": (1, H, W)}`` (or ``"lidar": (R,)``) float32; actions (4,) in [-1, 1]
(the task's ``action_mode``). An agent leaves ``agents`` once terminated or truncated, PettingZoo's convention.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from cufund.control import policy_observation as po
from cufund.core.config import ConfigError
from cufund.worlds.world import World

from .config import TaskConfig
from .observation_sensors import BatchRangeSensor, DepthCameraSpec, LidarSpec, SensorSpec, VehicleBoxes, sensor_spec
from .vector_env import CufundVectorEnv

__all__ = ["SwarmGatesEnv", "gates_world", "parallel_env", "vehicle_collisions"]


def gates_world(cfg: TaskConfig) -> World:
    """The ground and the gates of a gates task as frames around their square openings (gate_size), each flown along
    its +x."""
    world = World("swarm_gates")
    world.add_plane((60.0, 60.0), (0.0, 0.0, 0.0), label="ground")  # seen by the sensors; crash_z is the crash
    for x, y, z, yaw in cfg.targets:
        world.add_tunnel_frame((x, y, z), cfg.gate_size, cfg.gate_size, yaw=math.radians(yaw), label="gate")
    return world


def vehicle_collisions(p_W: np.ndarray, radius: float, present: np.ndarray) -> np.ndarray:
    """(N,) bool: vehicle i (present) has a present other within 2 ``radius`` (sphere overlap)."""
    p = np.asarray(p_W, dtype=np.float64)
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)
    close = (d < 2.0 * radius) & present[:, None] & present[None, :]
    np.fill_diagonal(close, False)
    return close.any(axis=1)


class SwarmGatesEnv(ParallelEnv):
    """See the module's docstring. ``sensor``: ``depth`` or ``lidar`` (or a spec) with ``sensor_params``; other
    keywords override the task YAML."""

    metadata = {"name": "cufund/SwarmGates-v0", "render_modes": [], "is_parallelizable": True}

    def __init__(
        self,
        num_agents: int = 3,
        *,
        sensor: str | SensorSpec = "depth",
        sensor_params: dict[str, Any] | None = None,
        collision_radius: float = 0.1,
        box_half_extents: tuple[float, float, float] = (0.1, 0.1, 0.04),
        spacing: float = 0.5,
        nthreads: int = 0,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        if isinstance(num_agents, bool) or not isinstance(num_agents, (int, np.integer)) or not 1 <= num_agents <= 256:
            raise ConfigError(f"num_agents must be a whole number in [1, 256], got {num_agents!r}")
        if render_mode is not None:
            raise ConfigError(f"render_mode must be None (cufund envs do not render), got {render_mode!r}")
        for name, value in (("collision_radius", collision_radius), ("spacing", spacing)):
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not (math.isfinite(value) and value > 0)
            ):
                raise ConfigError(f"{name} must be a finite number > 0 [m], got {value!r}")
        self.render_mode = None
        self.vector = CufundVectorEnv(int(num_agents), "swarm_gates", **overrides)
        cfg = self.config = self.vector.config
        if cfg.task != "gates":
            raise ConfigError(f"SwarmGates-v0 flies a gates task, got task {cfg.task!r}")
        self.collision_radius = float(collision_radius)
        self.world = gates_world(cfg)
        if isinstance(sensor, (DepthCameraSpec, LidarSpec)):
            spec: SensorSpec = sensor
        elif isinstance(sensor, str):
            defaults = {"width": 32, "height": 32, "range_max": 10.0} if sensor == "depth" else {}
            spec = sensor_spec(sensor, **(defaults | (sensor_params or {})))
        else:
            raise ConfigError(f"sensor must be 'depth', 'lidar' or a sensor spec, got {sensor!r}")
        self.sensor_key = "depth" if isinstance(spec, DepthCameraSpec) else "lidar"
        self.sensor = BatchRangeSensor(
            self.world.raycast_scene, spec, boxes=VehicleBoxes(box_half_extents), nthreads=nthreads
        )
        self.possible_agents = [f"drone_{i}" for i in range(int(num_agents))]
        self.agents: list[str] = []
        shape = (1, *spec.shape) if self.sensor_key == "depth" else spec.shape
        self._obs_space = gymnasium.spaces.Dict(
            {
                "state": self.vector.single_observation_space,
                self.sensor_key: gymnasium.spaces.Box(0.0, spec.range_max, shape, np.float32),
            }
        )
        self._act_space = self.vector.single_action_space
        yaw = math.radians(cfg.targets[0][3])
        across = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
        n = int(num_agents)
        self._offsets = (np.arange(n) - (n - 1) / 2.0)[:, None] * float(spacing) * across
        self._live = np.zeros(n, dtype=bool)
        self._frame = 0

    @functools.cache  # noqa: B019  (PettingZoo's documented pattern; one space per agent)
    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        return self._obs_space

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self._act_space

    def _observe(self, state: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
        b = self.vector.batch
        img = self.sensor.observe(np.asarray(b.p), np.asarray(b.q), frame=self._frame, present=self._live)
        self._frame += 1
        if self.sensor_key == "depth":
            img = img[:, None]
        return {
            a: {"state": state[i], self.sensor_key: img[i]} for i, a in enumerate(self.possible_agents) if self._live[i]
        }

    def _layout_state(self) -> np.ndarray:
        """The agents' noise-free reset observations where they stand (first gates, no previous action)."""
        b = self.vector.batch
        cfg = self.config
        k = cfg.n_ahead
        gates = [cfg.targets[min(j, len(cfg.targets) - 1)] for j in range(k)]
        n = len(self.possible_agents)
        tg = np.broadcast_to(np.array([g[:3] for g in gates]), (n, k, 3))
        normals = np.broadcast_to(
            np.array([[math.cos(math.radians(g[3])), math.sin(math.radians(g[3])), 0.0] for g in gates]), (n, k, 3)
        )
        return po.build_observation(
            tg, np.asarray(b.p), np.asarray(b.v), np.asarray(b.q), np.asarray(b.w), np.zeros((n, 4)), normals
        )

    def _spread(self, state: np.ndarray) -> np.ndarray:
        """Moves the agents apart into their row and rebuilds their reset observations ``state`` (the C++ task's)
        there, keeping the noise the task drew in them (none: the layout's numbers bit for bit)."""
        noise = np.asarray(state, dtype=np.float64) - self._layout_state()
        b = self.vector.batch
        b.p[:] = np.asarray(b.p) + self._offsets
        return (self._layout_state() + noise).astype(np.float32)

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict]]:
        state, _ = self.vector.reset(seed=seed, options=options)
        if seed is not None:
            self.sensor.seed = int(seed)
            self._frame = 0
        self.agents = list(self.possible_agents)
        self._live[:] = True
        state = self._spread(state)
        return self._observe(state), {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        n = len(self.possible_agents)
        a = np.zeros((n, 4))
        for i, name in enumerate(self.possible_agents):
            if self._live[i] and name in actions:
                a[i] = np.asarray(actions[name], dtype=np.float64).reshape(4)
        state, rew, term, trunc, _ = self.vector.step(a)
        b = self.vector.batch
        live = self._live.copy()
        hit = vehicle_collisions(np.asarray(b.p), self.collision_radius, live) & ~term
        rew = rew - self.config.rewards.crash * hit
        if hit.any():
            self.vector._core.end_episodes(hit)
        term = term | hit
        trunc = trunc & ~term
        obs = self._observe(state)
        names = [(i, name) for i, name in enumerate(self.possible_agents) if live[i]]
        rewards = {name: float(rew[i]) for i, name in names}
        terminations = {name: bool(term[i]) for i, name in names}
        truncations = {name: bool(trunc[i]) for i, name in names}
        infos: dict[str, dict] = {name: {"vehicle_collision": bool(hit[i])} for i, name in names}
        self._live &= ~(term | trunc)
        self.agents = [name for i, name in enumerate(self.possible_agents) if self._live[i]]
        return obs, rewards, terminations, truncations, infos

    def close(self) -> None:
        self.vector.close()


def parallel_env(num_agents: int = 3, **kwargs: Any) -> SwarmGatesEnv:
    """``cufund/SwarmGates-v0`` with ``num_agents`` agents (keywords: see :class:`SwarmGatesEnv`)."""
    return SwarmGatesEnv(num_agents, **kwargs)

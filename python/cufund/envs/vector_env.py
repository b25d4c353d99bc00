"""cufund's own Gymnasium VectorEnv over one QuadrotorBatch: every env is one vehicle of the batch.

Gymnasium >= 1.0 next-step autoreset (``metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP``): the step after
an env terminated or was truncated resets it and returns its first observation with reward 0, terminated and
truncated False; the action given for it in that step is ignored. One ``seed`` derives every stream: env ``i``
draws its resets (and its randomisation and noise) from stream ``seed + i``, as Gymnasium's SyncVectorEnv seeds
its envs, so env ``i`` of a vector equals a single env seeded ``seed + i`` bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from cufund import _core
from cufund.control import policy_observation as po
from cufund.control.rate_control import RateControlParams
from cufund.sensors.imu import imu_preset
from cufund.vehicle import presets

from .config import TaskConfig, load_task

__all__ = ["OBS_BOUND", "CufundVectorEnv", "GatesEnv", "HoverEnv", "WaypointsEnv", "make_config", "task_params"]

OBS_BOUND = 1.0e4
"""Bound of the observation space per entry."""


_TASK_IDS = {"hover": 0, "waypoints": 1, "gates": 2}
_MODE_IDS = {"rotor_speeds": 0, "thrust_rates": 1, "velocity": 2}
_RATE_I_SCALE = math.radians(400.0)  # as cufund.control.rate_control (PX4)


def task_params(cfg: TaskConfig) -> Any:
    """The task as the C++ batch reads it (cufund._core.envs.EnvTaskParams)."""
    t = _core.envs.EnvTaskParams()
    t.task = _TASK_IDS[cfg.task]
    t.action_mode = _MODE_IDS[cfg.action_mode]
    t.dt = cfg.dt
    t.substeps = cfg.substeps
    t.max_steps = cfg.max_steps
    gates = cfg.task == "gates"
    t.targets = [x for tg in cfg.targets for x in (*tg[:3], math.radians(tg[3]) if gates else 0.0)]
    t.n_ahead = cfg.n_ahead
    t.reach_radius = cfg.reach_radius
    t.gate_size = cfg.gate_size
    t.bound = cfg.bound_m
    t.crash_z = cfg.crash_z
    if gates:
        first = cfg.targets[0]
        yaw = math.radians(first[3])
        default = (first[0] - math.cos(yaw), first[1] - math.sin(yaw), first[2])
        t.spawn_center = list(cfg.start if cfg.start is not None else default)
    else:
        t.spawn_center = list(cfg.targets[0][:3])
    t.spawn_extent = list(cfg.spawn_extent)
    t.spawn_speed = cfg.spawn_speed
    t.spawn_tilt = math.radians(cfg.spawn_tilt_deg)
    t.spawn_rate = cfg.spawn_rate
    t.max_rate = cfg.max_rate
    t.max_speed = cfg.max_speed
    r = cfg.rewards
    t.w_position, t.w_velocity, t.w_rate, t.w_action = r.position, r.velocity, r.rate, r.action
    t.alive, t.progress, t.reached, t.crash = r.alive, r.progress, r.reached, r.crash
    t.w_smooth = r.smoothness
    t.segment_s, t.hold_s = list(cfg.segment_s), list(cfg.hold_s)
    t.waypoint_jitter, t.lookahead = list(cfg.waypoint_jitter_m), cfg.lookahead_s
    d = cfg.randomisation
    t.mass, t.inertia, t.motor_constant, t.motor_lag = (
        list(d.mass),
        list(d.inertia),
        list(d.motor_constant),
        list(d.motor_lag),
    )
    t.drag, t.latency_steps, t.wind = list(d.drag), list(d.latency_steps), list(d.wind_mps)
    t.position_noise, t.velocity_noise = list(d.position_noise_m), list(d.velocity_noise_mps)
    if cfg.imu_noise:
        white, walk, turn_on = imu_preset(cfg.imu).gyro.per_axis(3)
        t.imu_noise = True
        t.gyro_white, t.gyro_walk, t.gyro_turn_on = float(white[0]), float(walk[0]), float(turn_on[0])
    g = RateControlParams()
    t.set_rate_gains(
        (g.roll_p, g.pitch_p, g.yaw_p),
        (g.roll_i, g.pitch_i, g.yaw_i),
        (g.roll_d, g.pitch_d, g.yaw_d),
        g.feed_forward,
        g.integrator_limit,
    )
    t.rate_d_cutoff_hz = g.d_cutoff_hz
    t.rate_i_scale = _RATE_I_SCALE
    return t


def make_config(task: str | TaskConfig, overrides: dict[str, Any]) -> TaskConfig:
    """The task's configuration with keyword overrides (``gymnasium.make`` kwargs)."""
    if isinstance(task, TaskConfig):
        return task.replace(**overrides) if overrides else task
    return load_task(task, **overrides)


class CufundVectorEnv(VectorEnv):
    """``num_envs`` vehicles of one task (see :class:`HoverEnv`, :class:`WaypointsEnv`, :class:`GatesEnv` for each
    task's observation, reward and termination). Actions (num_envs, 4) in [-1, 1]; observations (num_envs, D)
    float32 in the layout of :mod:`cufund.control.policy_observation`.

    Actions (clipped to [-1, 1], delayed by the env's drawn latency):

    - ``rotor_speeds``: omega_i = omega_hover + a_i * span, span = min(omega_max - omega_hover,
      omega_hover - omega_min) of the nominal vehicle (a = 0 hovers the nominal vehicle);
    - ``thrust_rates``: collective thrust m g (1 + a_0) (capped at the rotors' maximum), body-rate setpoint
      a_1..3 * ``max_rate`` [rad/s], through cufund's rate loop (cpp/control RateControl with the default
      RateControlParams) at the env rate;
    - ``velocity``: velocity setpoint a_0..2 * ``max_speed`` [m/s] and yaw rate a_3 * ``max_rate``: acceleration
      4 (v_sp - v) + g z (z never below 0.2 g), thrust along the body z, tilt rate 10 1/s towards it, then the rate
      loop.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
    task_name = "hover"

    def __init__(self, num_envs: int = 1, task: str | TaskConfig | None = None, **overrides: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.config = cfg = make_config(task if task is not None else self.task_name, overrides)
        self.num_envs = int(num_envs)
        params = getattr(presets, cfg.vehicle)()
        self.params = dataclasses.replace(params, max_integration_step=cfg.dt / cfg.substeps)
        self._core = _core.envs.EnvBatch(self.params.to_core(), task_params(cfg), self.num_envs)
        self.obs_size = po.observation_size(cfg.n_ahead, cfg.target_dim)
        # finite bounds (check_env warns on infinite ones); a vehicle this far off was terminated long before
        self.single_observation_space = gymnasium.spaces.Box(-OBS_BOUND, OBS_BOUND, (self.obs_size,), np.float32)
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, (po.ACTION_SIZE,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Resets every env; ``seed`` seeds env ``i``'s stream with ``seed + i`` (else the streams go on)."""
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
                raise ValueError(f"seed must be an integer in [0, 2^63), got {seed!r}")
            return self._core.reset(int(seed)), {}
        return self._core.reset(), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """One step of every env (actions (num_envs, 4) in [-1, 1], clipped): obs, reward, terminated, truncated,
        infos (empty). Next-step autoreset (see the module's docstring)."""
        obs, rew, term, trunc = self._core.step(actions)
        return obs, rew, term, trunc, {}

    @property
    def batch(self) -> Any:
        """The C++ QuadrotorBatch the envs fly: ``p``, ``v``, ``q``, ``w``, ``rotor_speeds``, ... (N, k) views."""
        return self._core.batch

    @property
    def target_index(self) -> np.ndarray:
        """Per env, the index of the current target (waypoint or gate)."""
        return np.asarray(self._core.target_index)

    def reference(self, env: int, t: float) -> np.ndarray:
        """A timed-reference waypoints task: env ``env``'s reference p_W, v_W, a_W (9,) at time ``t`` [s] of its
        episode."""
        return np.asarray(self._core.reference(int(env), float(t)))

    def waypoints(self, env: int) -> np.ndarray:
        """A timed-reference waypoints task: env ``env``'s waypoints (K, 3) as moved at its last reset."""
        return np.asarray(self._core.waypoints(int(env)))


class HoverEnv(CufundVectorEnv):
    """Hover-v0: hold the point ``c = targets[0]`` (default (0, 0, 1) m, a Crazyflie).

    Start: position uniform in ``c +- spawn_extent``, velocity in ``+- spawn_speed``, roll and pitch in
    ``+- spawn_tilt_deg``, yaw in +-180 deg, body rate in ``+- spawn_rate``, rotors at the (drawn) vehicle's hover speed.
    Observation: one target block ``c - p_W``, then v_W, R_WB, w_B, a_prev (cufund.control.policy_observation).
    Reward per step, with e = |c - p_W| after the step and ``a`` the action given (clipped)::

        r = alive - position * e - velocity * |v_W| - rate * |w_B| - action * |a|^2  [- crash on a crash]

    Terminated (a crash): e > ``bound_m``, z < ``crash_z``, or a non-finite state. Truncated after
    ``episode_s * control_hz`` steps.
    """

    task_name = "hover"


class WaypointsEnv(CufundVectorEnv):
    """Waypoints-v0: fly through ``targets`` in order (default: the square scenario's 1 m square at 1.5 m).

    Start as Hover-v0 around the first waypoint. Observation: the next ``n_ahead`` waypoints relative to the vehicle
    (past the last, the last repeats), then v_W, R_WB, w_B, a_prev. Reward per step, with d (d_0) the distance to the
    current waypoint after (before) the step::

        r = alive - position * d - velocity * |v_W| - rate * |w_B| - action * |a|^2 + progress * (d_0 - d)
            [+ reached when d < reach_radius: the next waypoint becomes current] [- crash on a crash]

    Terminated: reaching the last waypoint (a success), or a crash (d > ``bound_m``, z < ``crash_z``, non-finite).
    Truncated after ``episode_s * control_hz`` steps.

    With a timed reference (``segment_s`` not [0, 0]), the target is a point r(t) that rests ``hold_s`` at each
    waypoint (each moved by +- ``waypoint_jitter_m`` per episode) and moves on to the next on a minimum-jerk segment
    of ``segment_s``; target block k is r + v_r tau + a_r tau^2 / 2 with tau = k * ``lookahead_s``
    (:func:`cufund.control.policy_observation.lookahead_targets`), and with d = |r - p_W|::

        r = alive - position * d - velocity * |v_W - v_r| - rate * |w_B| - action * |a|^2 [- crash on a crash]

    no progress or reached terms, no success: the episode runs to truncation. ``rewards.smoothness`` (every task)
    subtracts smoothness * |a - a_prev|^2.
    """

    task_name = "waypoints"


class GatesEnv(CufundVectorEnv):
    """Gates-v0: pass through square gates in order. A gate is [x, y, z, yaw_deg]: its centre c and normal
    n = (cos yaw, sin yaw, 0), the way through; the opening is ``gate_size`` square, the frame as wide again around it.

    Start: uniform in ``start +- spawn_extent`` (default start 1 m before the first gate). Observation: the next
    ``n_ahead`` gates as blocks of 6 (c - p_W, then n), then v_W, R_WB, w_B, a_prev. Reward as Waypoints-v0 with d
    the distance to the current gate's centre, and ``reached`` when the step's chord crosses the gate's plane forwards
    (n . (p - c) from < 0 to >= 0) inside the opening; crossing it in the frame is a crash, outside it nothing.
    Terminated: passing the last gate (a success), or a crash (the frame, d > ``bound_m``, z < ``crash_z``,
    non-finite). Truncated after ``episode_s * control_hz`` steps.
    """

    task_name = "gates"

"""A learning task's configuration: YAML (python/cufund/envs/tasks/*.yaml) validated into frozen dataclasses.

``gymnasium.make("cufund/Hover-v0", **overrides)`` and ``make_vec`` read the task's YAML and apply keyword
overrides on top (``action_mode="thrust_rates"``, ``randomisation={"mass": [0.9, 1.1]}``, ...). A wrong key or
value raises :class:`cufund.core.config.ConfigError` naming the field and what was expected.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cufund.core.config import ConfigError, from_dict, load_yaml, nested

__all__ = ["ACTION_MODES", "TASKS", "Randomisation", "Rewards", "TaskConfig", "load_task"]

TASKS = ("hover", "waypoints", "gates")
ACTION_MODES = ("rotor_speeds", "thrust_rates", "velocity")
TASK_DIR = Path(__file__).resolve().parent / "tasks"


def _range(where: str, value: Any, lo: float = 0.0, integer: bool = False) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where} must be a range [low, high] of two numbers, got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b):
        raise ConfigError(f"{where} must be a range [low, high] with {lo:g} <= low <= high, finite, got {value!r}")
    if integer and (a != int(a) or b != int(b)):
        raise ConfigError(f"{where} must be a range of whole numbers [low, high], got {value!r}")
    return (a, b)


def _vec(where: str, value: Any, n: int) -> tuple[float, ...]:
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where} must be {n} numbers, got {value!r}") from None
    if len(v) != n or not all(math.isfinite(x) for x in v):
        raise ConfigError(f"{where} must be {n} finite numbers, got {value!r}")
    return v


def _positive(where: str, value: Any, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ConfigError(f"{where} must be a finite number {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return v


@dataclass(frozen=True)
class Randomisation:
    """Domain randomisation: each env draws its values at every reset from its own seeded stream, uniformly in
    the ranges given. Scales multiply the vehicle preset's value; [1, 1] (the default) leaves it as it is.
    Everything defaults to off: a task that asks for none runs the preset unchanged."""

    mass: tuple[float, float] = (1.0, 1.0)
    """Scale of the mass []."""
    inertia: tuple[float, float] = (1.0, 1.0)
    """Scale of the inertia matrix (all entries, one draw) []."""
    motor_constant: tuple[float, float] = (1.0, 1.0)
    """Scale of the thrust coefficient k_f (the reaction torque follows, c_m being a ratio) []."""
    motor_lag: tuple[float, float] = (1.0, 1.0)
    """Scale of the motor time constant tau_m []."""
    drag: tuple[float, float] = (1.0, 1.0)
    """Scale of the rotor drag and the body drag coefficients []."""
    latency_steps: tuple[float, float] = (0.0, 0.0)
    """Action delay [env steps], a whole number drawn in [low, high]: the action applied is the one given this many
    steps before (zeros before the first)."""
    wind_mps: tuple[float, float] = (0.0, 0.0)
    """Constant wind speed [m/s], horizontal, in a uniformly drawn direction."""
    position_noise_m: tuple[float, float] = (0.0, 0.0)
    """Standard deviation [m] of white noise on the observed target offsets, drawn per env."""
    velocity_noise_mps: tuple[float, float] = (0.0, 0.0)
    """Standard deviation [m/s] of white noise on the observed velocity, drawn per env."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            lo = 1e-3 if f.name in ("mass", "inertia", "motor_constant", "motor_lag") else 0.0
            v = _range(f"randomisation.{f.name}", getattr(self, f.name), lo, integer=f.name == "latency_steps")
            object.__setattr__(self, f.name, v)
        if self.latency_steps[1] > 64:
            raise ConfigError(f"randomisation.latency_steps must be at most 64 steps, got {self.latency_steps!r}")

    @property
    def physical(self) -> bool:
        """True when any vehicle parameter is drawn per env (so each env has its own dynamics constants)."""
        return any(getattr(self, n) != (1.0, 1.0) for n in ("mass", "inertia", "motor_constant", "motor_lag", "drag"))


@dataclass(frozen=True)
class Rewards:
    """Reward weights (each task's docstring gives its formula)."""

    position: float = 1.0
    """Per metre of distance to the current target [1/m]."""
    velocity: float = 0.05
    """Per m/s of speed (hover) [s/m]."""
    rate: float = 0.02
    """Per rad/s of body rate [s/rad]."""
    action: float = 0.01
    """Per unit of |a|^2 []."""
    alive: float = 1.0
    """Every step not terminated []."""
    progress: float = 10.0
    """Per metre of distance to the current target gained in the step (waypoints, gates) [1/m]."""
    reached: float = 10.0
    """On reaching a waypoint or passing a gate []."""
    crash: float = 10.0
    """Subtracted on a crash or leaving the bounds (the step that terminates) []."""
    smoothness: float = 0.0
    """Per unit of |a - a_prev|^2, the change of action in the step (0: off) []."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _positive(f"rewards.{f.name}", getattr(self, f.name), True))


@dataclass(frozen=True)
class TaskConfig:
    """One learning task. Positions [m] world ENU; times [s]."""

    name: str
    """The task's name (Hover-v0, ...)."""
    task: str
    """``hover``, ``waypoints`` or ``gates``."""
    vehicle: str = "crazyflie"
    """A vehicle preset (cufund.vehicle.presets)."""
    action_mode: str = "rotor_speeds"
    """``rotor_speeds``, ``thrust_rates`` (collective thrust + body rates through cufund's rate loop) or
    ``velocity`` (a velocity setpoint through a velocity loop and the rate loop); actions in [-1, 1]^4 in all."""
    control_hz: float = 100.0
    """Env steps per simulated second [Hz]."""
    substeps: int = 1
    """RK4 steps of the dynamics per env step."""
    episode_s: float = 5.0
    """Episode length [s]: truncated after round(episode_s * control_hz) steps."""
    targets: tuple[tuple[float, ...], ...] = ((0.0, 0.0, 1.0),)
    """Hover: one point [x, y, z]; waypoints: the points in order; gates: [x, y, z, yaw_deg] per gate (the gate's
    normal, the way through it, is its +x at that yaw)."""
    n_ahead: int = 1
    """Target blocks in the observation (the next ones; past the last, the last repeats)."""
    reach_radius: float = 0.1
    """Waypoints: a waypoint counts as reached within this distance [m]."""
    gate_size: float = 0.5
    """Gates: side of the square opening [m]; crossing the gate's plane outside it is a crash."""
    spawn_extent: tuple[float, float, float] = (0.5, 0.5, 0.5)
    """Initial position: uniform in +- this box [m] around the first target (hover, waypoints) or start."""
    start: tuple[float, float, float] | None = None
    """Gates: the box's centre [m] (default: 1 m before the first gate)."""
    spawn_speed: float = 0.2
    """Initial velocity: uniform in +- this per axis [m/s]."""
    spawn_tilt_deg: float = 10.0
    """Initial roll and pitch: uniform in +- this [deg]; yaw uniform in +- 180 deg."""
    spawn_rate: float = 0.5
    """Initial body rate: uniform in +- this per axis [rad/s]."""
    bound_m: float = 2.0
    """Terminated (a crash) farther than this from the current target [m]."""
    crash_z: float = 0.02
    """Terminated (a crash) below this height [m]."""
    max_rate: float = 10.0
    """thrust_rates: body-rate setpoint at |a| = 1 [rad/s]."""
    max_speed: float = 2.0
    """velocity: speed setpoint at |a| = 1 per axis [m/s]."""
    imu_noise: bool = False
    """Observe w_B through the IMU noise model: the gyro's turn-on bias, bias random walk and white noise of the
    IMU preset ``imu``, sampled at the env step (``cufund.sensors.noise.ErrorProcess``'s model)."""
    imu: str = "bmi088"
    """The IMU preset whose gyro noise ``imu_noise`` uses (cufund.sensors.imu.IMU_PRESETS)."""
    segment_s: tuple[float, float] = (0.0, 0.0)
    """Waypoints with a timed reference: the target is a point moving from waypoint to waypoint on minimum-jerk
    segments, each taking a duration drawn in [low, high] [s] per episode; [0, 0] (the default) is off (the
    target switches to the next waypoint on arrival)."""
    hold_s: tuple[float, float] = (0.0, 0.0)
    """Timed reference: the rest at each waypoint before the reference leaves it, drawn in [low, high] [s]."""
    waypoint_jitter_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Timed reference: every waypoint moves by a uniform draw in +- this per axis [m] at each reset (the spawn
    box moves with the first)."""
    lookahead_s: float = 0.0
    """Timed reference: target block k is the reference extrapolated k * lookahead_s ahead, p + v tau + a tau^2 / 2
    (block 0 the reference itself; the policy controller builds the same from the trajectory setpoint)."""
    rewards: Rewards = field(default_factory=Rewards)
    randomisation: Randomisation = field(default_factory=Randomisation)

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise ConfigError(f"task must be one of {', '.join(TASKS)}, got {self.task!r}")
        if self.action_mode not in ACTION_MODES:
            raise ConfigError(f"action_mode must be one of {', '.join(ACTION_MODES)}, got {self.action_mode!r}")
        from cufund.vehicle import presets

        if self.vehicle not in presets.__all__:
            raise ConfigError(f"vehicle must be a preset ({', '.join(presets.__all__)}), got {self.vehicle!r}")
        for name in ("control_hz", "episode_s", "reach_radius", "gate_size", "bound_m", "max_rate", "max_speed"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        for name in ("spawn_speed", "spawn_tilt_deg", "spawn_rate"):
            object.__setattr__(self, name, _positive(name, getattr(self, name), True))
        object.__setattr__(self, "crash_z", _vec("crash_z", [self.crash_z], 1)[0])
        for name in ("substeps", "n_ahead"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 1000:
                raise ConfigError(f"{name} must be a whole number in [1, 1000], got {v!r}")
        if round(self.episode_s * self.control_hz) < 1:
            raise ConfigError("episode_s * control_hz must be at least 1 step")
        dim = 4 if self.task == "gates" else 3
        if not isinstance(self.targets, (list, tuple)) or len(self.targets) < 1:
            raise ConfigError(f"targets must be a non-empty list of [x, y, z{', yaw_deg' if dim == 4 else ''}]")
        if self.task == "hover" and len(self.targets) != 1:
            raise ConfigError(f"targets of a hover task must be one point [x, y, z], got {len(self.targets)}")
        tg = tuple(_vec(f"targets[{i}]", t, dim) for i, t in enumerate(self.targets))
        object.__setattr__(self, "targets", tg)
        object.__setattr__(self, "spawn_extent", _vec("spawn_extent", self.spawn_extent, 3))
        if any(x < 0 for x in self.spawn_extent):
            raise ConfigError(f"spawn_extent must be >= 0 per axis [m], got {self.spawn_extent!r}")
        if self.start is not None:
            object.__setattr__(self, "start", _vec("start", self.start, 3))
        from cufund.sensors.imu import IMU_PRESETS

        if self.imu not in IMU_PRESETS:
            raise ConfigError(f"imu must be an IMU preset ({', '.join(IMU_PRESETS)}), got {self.imu!r}")
        if not isinstance(self.imu_noise, bool):
            raise ConfigError(f"imu_noise must be true or false, got {self.imu_noise!r}")
        object.__setattr__(self, "segment_s", _range("segment_s", self.segment_s))
        object.__setattr__(self, "hold_s", _range("hold_s", self.hold_s))
        object.__setattr__(self, "waypoint_jitter_m", _vec("waypoint_jitter_m", self.waypoint_jitter_m, 3))
        if any(x < 0 for x in self.waypoint_jitter_m):
            raise ConfigError(f"waypoint_jitter_m must be >= 0 per axis [m], got {self.waypoint_jitter_m!r}")
        object.__setattr__(self, "lookahead_s", _positive("lookahead_s", self.lookahead_s, True))
        if self.timed_reference:
            if self.task != "waypoints":
                raise ConfigError(f"segment_s (a timed reference) is for the waypoints task, not {self.task!r}")
            if self.segment_s[0] <= 0:
                raise ConfigError(f"segment_s must be [low, high] with 0 < low <= high [s], got {self.segment_s!r}")
        else:  # the timed reference's other keys mean nothing without it: refused rather than ignored
            for name, on in (
                ("hold_s", self.hold_s[1] > 0),
                ("waypoint_jitter_m", any(x > 0 for x in self.waypoint_jitter_m)),
                ("lookahead_s", self.lookahead_s > 0),
            ):
                if on:
                    raise ConfigError(f"{name} is for a timed reference: set segment_s too (now [0, 0], off)")
        object.__setattr__(self, "rewards", nested(Rewards, self.rewards, "rewards"))
        object.__setattr__(self, "randomisation", nested(Randomisation, self.randomisation, "randomisation"))

    @property
    def timed_reference(self) -> bool:
        """True when the waypoints are flown along a timed reference (``segment_s`` not [0, 0])."""
        return self.segment_s[1] > 0

    @property
    def max_steps(self) -> int:
        """Steps until truncation."""
        return int(round(self.episode_s * self.control_hz))

    @property
    def dt(self) -> float:
        """One env step [s]."""
        return 1.0 / self.control_hz

    @property
    def target_dim(self) -> int:
        """Numbers per target block in the observation (cufund.control.policy_observation)."""
        return 6 if self.task == "gates" else 3

    def replace(self, **overrides: Any) -> TaskConfig:
        """A copy with ``overrides`` (nested sections as mappings merge into the section)."""
        data = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        for key, value in overrides.items():
            if key in ("rewards", "randomisation") and isinstance(value, dict):
                base = dataclasses.asdict(data[key])
                base.update(value)
                value = base
            data[key] = value
        return from_dict(TaskConfig, data, "task")


def load_task(name_or_path: str | Path, **overrides: Any) -> TaskConfig:
    """The task ``hover``/``waypoints``/``gates`` (its YAML in python/cufund/envs/tasks/) or a YAML file's path, with
    keyword ``overrides``."""
    p = Path(name_or_path)
    if not p.suffix:
        p = TASK_DIR / f"{name_or_path}.yaml"
        if not p.exists():
            known = sorted(f.stem for f in TASK_DIR.glob("*.yaml"))
            raise ConfigError(f"unknown task {str(name_or_path)!r}; expected one of: {', '.join(known)}")
    data = load_yaml(p)
    cfg = from_dict(TaskConfig, data, str(p.name))
    return cfg.replace(**overrides) if overrides else cfg

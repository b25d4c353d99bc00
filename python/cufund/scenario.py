"""Scenarios: a YAML file naming the vehicle, controller and gains, trajectory, rates, duration and seed,
validated into frozen dataclasses and run on the :class:`~cufund.simulator.Simulator`."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import presets
from .config import ConfigError, check_real_fields, from_dict, load_yaml, nested, to_dict
from .control import (AttitudeControlParams, AttitudeController, GeometricControlParams, GeometricController,
                      PositionControlParams, PositionController, RateControlParams, RateController)
from .messages import Topics
from .params import QuadrotorParams
from .planning import Hold, JerkLimitedMove, MinimumSnapTrajectory, TrajectoryFollower, TrajectorySequence
from .quadrotor import Quadrotor
from .sensors import (BAROMETER_PRESETS, GPS_PRESETS, IMU_PRESETS, BarometerParams, BarometerSensor, GpsParams,
                      GpsSensor, ImuParams, ImuSensor, MagnetometerParams, MagnetometerSensor)
from .simulator import SimulationResult, Simulator

__all__ = ["ControllerConfig", "RatesConfig", "ScenarioConfig", "ScenarioRun", "SensorsConfig", "TrajectoryConfig",
           "available_scenarios", "load_scenario", "run_scenario"]

_PRESETS = {"crazyflie": presets.crazyflie, "iris": presets.iris, "cu_astro": presets.cu_astro}


@dataclass(frozen=True)
class RatesConfig:
    """Component rates [Hz]; each must divide ``physics_hz``."""

    physics_hz: float = 1000.0
    """Physics (RK4) steps per second."""
    trajectory_hz: float = 250.0
    """Trajectory setpoints."""
    position_hz: float = 250.0
    """Cascaded PID: position and velocity loop."""
    attitude_hz: float = 250.0
    """Cascaded PID: attitude loop."""
    rate_hz: float = 500.0
    """Cascaded PID: body-rate loop and allocation."""
    geometric_hz: float = 500.0
    """Geometric controller."""

    def __post_init__(self) -> None:
        check_real_fields(self, "rates", positive=True, unit=" [Hz]")


@dataclass(frozen=True)
class ControllerConfig:
    """Which controller flies, and the gains of each (only the chosen one's are used)."""

    kind: str = "pid"
    """``pid`` (PX4-style cascade) or ``geometric`` (SE(3), Lee et al. 2010)."""
    position: PositionControlParams = field(default_factory=PositionControlParams)
    attitude: AttitudeControlParams = field(default_factory=AttitudeControlParams)
    rate: RateControlParams = field(default_factory=RateControlParams)
    geometric: GeometricControlParams = field(default_factory=GeometricControlParams)

    def __post_init__(self) -> None:
        if self.kind not in ("pid", "geometric"):
            raise ConfigError(f"controller.kind must be 'pid' or 'geometric', got {self.kind!r}")
        for name, cls in (("position", PositionControlParams), ("attitude", AttitudeControlParams),
                          ("rate", RateControlParams), ("geometric", GeometricControlParams)):
            try:
                object.__setattr__(self, name, nested(cls, getattr(self, name), f"controller.{name}"))
            except ValueError as e:
                raise ConfigError(str(e) if "controller." in str(e) else f"controller.{name}: {e}") from None


@dataclass(frozen=True)
class TrajectoryConfig:
    """Take off from the first waypoint's ground point, hover, fly a minimum-snap path through the waypoints,
    hover, land below the last waypoint."""

    waypoints: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 1.5), (1.0, 0.0, 1.5), (1.0, 1.0, 1.5),
                                                         (0.0, 1.0, 1.5), (0.0, 0.0, 1.5))
    """Min-snap waypoints, world ENU [m]."""
    yaw: tuple[float, ...] | None = None
    """Yaw at each waypoint [rad]; zeros if null."""
    v_max: float = 1.0
    """Min-snap time allocation: peak speed [m/s]."""
    a_max: float = 2.0
    """Min-snap time allocation: peak acceleration [m/s^2]."""
    move_v_max: float = 1.0
    """Take-off and landing (ruckig): velocity limit [m/s]."""
    move_a_max: float = 2.0
    """Take-off and landing: acceleration limit [m/s^2]."""
    move_j_max: float = 5.0
    """Take-off and landing: jerk limit [m/s^3]."""
    hover_s: float = 1.0
    """Hover before and after the min-snap path [s]."""

    def __post_init__(self) -> None:
        w = np.asarray(self.waypoints, dtype=float) if self.waypoints is not None else np.zeros(0)
        if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 2 or not np.all(np.isfinite(w)):
            raise ConfigError(f"trajectory.waypoints must be a list of at least 2 [x, y, z] points [m], got shape {w.shape}")
        if np.any(w[:, 2] <= 0.1):
            raise ConfigError("trajectory.waypoints must all be above 0.1 m (the path is flown after take-off)")
        object.__setattr__(self, "waypoints", tuple(tuple(float(x) for x in r) for r in w))
        if self.yaw is not None:
            y = np.asarray(self.yaw, dtype=float)
            if y.shape != (w.shape[0],) or not np.all(np.isfinite(y)):
                raise ConfigError(f"trajectory.yaw must have one finite angle per waypoint ({w.shape[0]}) [rad], "
                                  f"got {[float(v) for v in y]}")
            object.__setattr__(self, "yaw", tuple(float(v) for v in y))
        for name in ("v_max", "a_max", "move_v_max", "move_a_max", "move_j_max", "hover_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 or (v == 0 and name != "hover_s"):
                raise ConfigError(f"trajectory.{name} must be a number > 0, got {v!r}")
            object.__setattr__(self, name, float(v))


_SENSOR_KINDS = {
    # name: (params class, presets, component class, stream index of its seed)
    "imu": (ImuParams, IMU_PRESETS, ImuSensor, 0),
    "magnetometer": (MagnetometerParams, {"default": MagnetometerParams}, MagnetometerSensor, 1),
    "barometer": (BarometerParams, BAROMETER_PRESETS, BarometerSensor, 2),
    "gps": (GpsParams, GPS_PRESETS, GpsSensor, 3),
}


@dataclass(frozen=True)
class SensorsConfig:
    """Inertial and navigation sensors to attach: each null (none), a preset name, or a mapping of its
    parameters (:class:`~cufund.sensors.ImuParams`, ``MagnetometerParams``, ``BarometerParams``, ``GpsParams``).
    Each gets its own random stream, seeded from the scenario's seed and the sensor's kind."""

    imu: Any = None
    """e.g. ``icm42688p`` or ``bmi088``."""
    magnetometer: Any = None
    """``default`` or a mapping."""
    barometer: Any = None
    """e.g. ``ms5611``."""
    gps: Any = None
    """e.g. ``ublox_m8n`` or ``ublox_m9n``."""

    def __post_init__(self) -> None:
        for kind in _SENSOR_KINDS:
            self.params(kind)  # validates

    def params(self, kind: str) -> Any:
        """The parameters of sensor ``kind``, or None when it is not attached."""
        cls, known, _, _ = _SENSOR_KINDS[kind]
        value = getattr(self, kind)
        if value is None or isinstance(value, cls):
            return value
        if isinstance(value, str):
            if value not in known:
                raise ConfigError(f"sensors.{kind} must be one of {', '.join(known)} or a mapping, got {value!r}")
            return known[value]()
        return from_dict(cls, value, f"sensors.{kind}")

    def components(self, seed: int, gravity: float) -> list[Any]:
        """The attached sensors as simulator components, each with its own seed."""
        out = []
        for kind, (_, _, component, stream) in _SENSOR_KINDS.items():
            params = self.params(kind)
            if params is None:
                continue
            sensor_seed = int(np.random.SeedSequence([seed, stream]).generate_state(1)[0])
            extra = {"gravity": gravity} if component is ImuSensor else {}  # the IMU senses gravity
            out.append(component(params, sensor_seed, **extra))
        return out


@dataclass(frozen=True)
class ScenarioConfig:
    """A complete, reproducible run."""

    name: str = "custom"
    vehicle: Any = "cu_astro"
    """A preset name (cu_astro, crazyflie, iris) or a mapping of :class:`QuadrotorParams` fields."""
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    rates: RatesConfig = field(default_factory=RatesConfig)
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    duration: float = 60.0
    """Longest simulated time [s]; the run ends earlier (completed) once the vehicle has landed."""
    seed: int = 0
    """Seed of every random source (sensor noise); the same seed repeats a run bit for bit."""

    def __post_init__(self) -> None:
        if isinstance(self.vehicle, str):
            if self.vehicle not in _PRESETS:
                raise ConfigError(f"vehicle must be one of {', '.join(_PRESETS)} or a mapping of QuadrotorParams fields, "
                                  f"got {self.vehicle!r}")
        elif isinstance(self.vehicle, dict):
            try:
                QuadrotorParams.from_dict(self.vehicle)
            except ValueError as e:
                raise ConfigError(f"vehicle: {e}") from None
        else:
            raise ConfigError(f"vehicle must be a preset name or a mapping, got {type(self.vehicle).__name__}")
        object.__setattr__(self, "controller", nested(ControllerConfig, self.controller, "controller"))
        object.__setattr__(self, "trajectory", nested(TrajectoryConfig, self.trajectory, "trajectory"))
        object.__setattr__(self, "rates", nested(RatesConfig, self.rates, "rates"))
        object.__setattr__(self, "sensors", nested(SensorsConfig, self.sensors, "sensors"))
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        check_real_fields(self, "scenario", positive=True, unit=" [s]", names=("duration",))
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"seed must be an integer >= 0, got {self.seed!r}")

    def vehicle_params(self) -> QuadrotorParams:
        return _PRESETS[self.vehicle]() if isinstance(self.vehicle, str) else QuadrotorParams.from_dict(self.vehicle)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ScenarioConfig:
        return from_dict(cls, data, "scenario")

    def to_dict(self) -> dict[str, Any]:
        """Plain data (for ``config.yaml``) that :meth:`from_dict` turns back into an equal scenario."""
        return to_dict(self)

    def replace(self, **changes: Any) -> ScenarioConfig:
        return dataclasses.replace(self, **changes)


def _scenario_dir() -> Path:
    return Path(__file__).resolve().parent / "scenarios"


def available_scenarios() -> dict[str, str]:
    """Built-in scenario names and their one-line descriptions (the YAML's first comment line)."""
    out = {}
    for p in sorted(_scenario_dir().glob("*.yaml")):
        first = p.read_text(encoding="utf-8").splitlines()[0]
        out[p.stem] = first.lstrip("# ").strip()
    return out


def load_scenario(name_or_path: str | Path) -> ScenarioConfig:
    """A built-in scenario by name (see :func:`available_scenarios`) or a YAML file."""
    p = Path(name_or_path)
    if not p.suffix and not p.exists():
        p = _scenario_dir() / f"{name_or_path}.yaml"
        if not p.exists():
            raise ConfigError(f"unknown scenario {name_or_path!r}; built-in: {', '.join(available_scenarios())}")
    return ScenarioConfig.from_dict(load_yaml(p))


@dataclass
class ScenarioRun:
    """A finished scenario: the simulator's result, the flown reference, and the tracking metrics."""

    config: ScenarioConfig
    result: SimulationResult
    reference: TrajectorySequence
    path: MinimumSnapTrajectory
    """The min-snap part, over which tracking error is measured."""
    metrics: dict[str, Any]


def build_reference(cfg: TrajectoryConfig) -> tuple[TrajectorySequence, MinimumSnapTrajectory]:
    w = np.asarray(cfg.waypoints)
    yaw = None if cfg.yaw is None else np.asarray(cfg.yaw)
    yaw0 = 0.0 if yaw is None else float(yaw[0])
    ground = np.array([w[0, 0], w[0, 1], 0.0])
    takeoff = JerkLimitedMove(ground, w[0], cfg.move_v_max, cfg.move_a_max, cfg.move_j_max, yaw0, t_start=0.0)
    hover1 = Hold(w[0], cfg.hover_s, yaw0, t_start=takeoff.t_end)
    path = MinimumSnapTrajectory(w, yaw, v_max=cfg.v_max, a_max=cfg.a_max, t_start=hover1.t_end)
    yaw_end = float(path.yaw_waypoints[-1])
    hover2 = Hold(w[-1], cfg.hover_s, yaw_end, t_start=path.t_end)
    landing = JerkLimitedMove(w[-1], np.array([w[-1, 0], w[-1, 1], 0.0]), cfg.move_v_max, cfg.move_a_max,
                              cfg.move_j_max, yaw_end, t_start=hover2.t_end)
    return TrajectorySequence([takeoff, hover1, path, hover2, landing]), path


def run_scenario(config: ScenarioConfig, progress: bool = False, extra_components: tuple = ()) -> ScenarioRun:
    """Builds the vehicle, reference, simulator and controllers of ``config``, runs it, measures tracking.

    Tracking error is ``|p_W(t) - p_ref(t)|``: the true position against the min-snap trajectory evaluated at
    the same time, at every physics step from the path's first to its last waypoint time.
    """
    params = config.vehicle_params()
    rates = config.rates
    reference, path = build_reference(config.trajectory)
    quad = Quadrotor(params)
    w0 = np.asarray(config.trajectory.waypoints[0])
    quad.state.p[:] = (w0[0], w0[1], 0.0)  # on the ground below the first waypoint, rotors stopped
    sensors = config.sensors.components(config.seed, params.gravity)
    sim = Simulator(quad, physics_rate_hz=rates.physics_hz,
                    record_topics=(Topics.TRAJECTORY_SETPOINT, Topics.ATTITUDE_SETPOINT, Topics.ACTUATOR_COMMAND,
                                   *(sensor.topic for sensor in sensors)))
    for sensor in sensors:  # sensors first: within a tick, they measure the state the controllers see
        sim.add(sensor)
    sim.add(TrajectoryFollower(reference, rate_hz=rates.trajectory_hz))
    c = config.controller
    if c.kind == "pid":
        sim.add(PositionController(params, c.position, rate_hz=rates.position_hz))
        sim.add(AttitudeController(c.attitude, rate_hz=rates.attitude_hz))
        sim.add(RateController(params, c.rate, rate_hz=rates.rate_hz))
    else:
        sim.add(GeometricController(params, c.geometric, rate_hz=rates.geometric_hz))
    for comp in extra_components:
        sim.add(comp)
    t_landed = reference.t_end

    def landed(t: float, truth: Any) -> bool:
        return t >= t_landed and truth.p_W[2] < 0.02 and float(np.linalg.norm(truth.v_W)) < 0.05

    result = sim.run(config.duration, done=landed, progress=progress)
    return ScenarioRun(config, result, reference, path, tracking_metrics(result, path))


def tracking_metrics(result: SimulationResult, path: MinimumSnapTrajectory) -> dict[str, Any]:
    t = result.states["t"]
    m = (t >= path.t_knots[0]) & (t <= path.t_end)
    if not np.any(m):
        err = np.array([math.nan])
    else:
        err = np.linalg.norm(result.states["p_W"][m] - path.sample(t[m]).p_W, axis=1)
    return {
        "status": result.status.value,
        "message": result.message,
        "tracking_rmse_m": float(np.sqrt(np.mean(err ** 2))),
        "tracking_max_m": float(np.max(err)),
        "tracking_min_m": float(np.min(err)),
        "tracking_window_s": [float(path.t_knots[0]), float(path.t_end)],
        "tracking_samples": int(np.count_nonzero(m)),
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "real_time_factor": result.real_time_factor,
    }

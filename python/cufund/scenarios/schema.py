"""Scenarios as data: a YAML file describing a pipeline — world, vehicle, sensors, estimator, mapper, planner,
controller, mission — validated into frozen dataclasses before anything runs.

Each part is ``{kind: NAME, ...params}`` (a bare ``NAME`` is ``{kind: NAME}``; ``null`` leaves it out), the kind
looked up in :mod:`cufund.core.registry`. Every part also takes ``latency_s`` and ``phase_s``; sensors also ``topic``
and their extrinsic (``T_BI``, ``T_BL``, ``T_BC``). Dotted overrides (``controller.kind=geometric``,
``sensors.imu.rate_hz=400``, ``world.seed=3``) apply to the plain data before validation
(:func:`apply_overrides`). Building and running: :mod:`cufund.scenarios.build`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, check_real_fields, from_dict, load_yaml, load_yaml_text, nested, to_dict
from cufund.core.registry import extrinsic_keys, lookup, sensor_type
from cufund.core.topics import Topic
from cufund.geometry import Transform
from cufund.missions.failsafe_params import parse_failsafe
from cufund.sensors.faults import faults_to_data, parse_faults
from cufund.sensors.power_monitor import PowerSystem
from cufund.vehicle import presets
from cufund.vehicle.ground_effect import GroundEffectConfig
from cufund.vehicle.params import QuadrotorParams
from cufund.worlds.atmosphere import AtmosphereConfig
from cufund.worlds.downwash import DownwashConfig

from .fleet_schema import parse_vehicles, vehicles_to_data
from .plausibility import check_plausible
from .realism import RealismConfig

__all__ = [
    "LogConfig",
    "PartSpec",
    "RatesConfig",
    "ScenarioConfig",
    "TrajectoryConfig",
    "apply_overrides",
    "available_scenarios",
    "load_scenario",
    "parse_overrides",
]

_PRESETS = {"crazyflie": presets.crazyflie, "iris": presets.iris, "cu_astro": presets.cu_astro}
# the old shorthand `sensors: {magnetometer: default, imu: ideal}`
_SHORTHAND = {
    ("magnetometer", "default"): "magnetometer",
    ("imu", "ideal"): "ideal_imu",
    ("barometer", "ideal"): "ideal_barometer",
    ("gps", "ideal"): "ideal_gps",
}
_PART_GROUPS = ("world", "estimator", "mapper", "perception", "planner", "controller", "mission")


@dataclass(frozen=True)
class RatesConfig:
    """Physics and built-in component rates [Hz] (any positive rates; the physics grid is split at events)."""

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
        for f in dataclasses.fields(self):
            if getattr(self, f.name) > 1e6:
                raise ConfigError(f"rates.{f.name} must be at most 1e6 Hz, got {getattr(self, f.name)!r}")


@dataclass(frozen=True)
class TrajectoryConfig:
    """Take off from the first waypoint's ground point, hover, fly a minimum-snap path through the waypoints,
    hover, land below the last waypoint (the ``waypoints`` planner)."""

    waypoints: tuple[tuple[float, float, float], ...] = (
        (0.0, 0.0, 1.5),
        (1.0, 0.0, 1.5),
        (1.0, 1.0, 1.5),
        (0.0, 1.0, 1.5),
        (0.0, 0.0, 1.5),
    )
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
    corridor: float | None = None
    """Half-width of the tube around the waypoint polyline the min-snap path must stay in [m] (waypoints are
    inserted where it would leave it); null: no tube."""
    optimize_times: bool = False
    """Optimise the segment times for least snap before scaling to v_max / a_max (Mellinger & Kumar)."""

    def __post_init__(self) -> None:
        if self.corridor is not None:
            c = self.corridor
            if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) or c <= 0:
                raise ConfigError(f"trajectory.corridor must be a half-width > 0 [m] or null, got {c!r}")
            object.__setattr__(self, "corridor", float(c))
        if not isinstance(self.optimize_times, bool):
            raise ConfigError(f"trajectory.optimize_times must be true or false, got {self.optimize_times!r}")
        try:
            w = np.asarray(self.waypoints, dtype=float) if self.waypoints is not None else np.zeros(0)
        except (TypeError, ValueError):
            raise ConfigError(
                f"trajectory.waypoints must be a list of [x, y, z] points [m], got {self.waypoints!r}"
            ) from None
        if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 2 or not np.all(np.isfinite(w)):
            raise ConfigError(
                f"trajectory.waypoints must be a list of at least 2 [x, y, z] points [m], got shape {w.shape}"
            )
        if np.any(w[:, 2] <= 0.1):
            raise ConfigError("trajectory.waypoints must all be above 0.1 m (the path is flown after take-off)")
        if np.any(np.abs(w) > 1e5):
            raise ConfigError("trajectory.waypoints must lie within 1e5 m of the origin")
        object.__setattr__(self, "waypoints", tuple(tuple(float(x) for x in r) for r in w))
        if self.yaw is not None:
            try:
                y = np.asarray(self.yaw, dtype=float)
            except (TypeError, ValueError):
                y = np.full(1, np.nan)
            if y.shape != (w.shape[0],) or not np.all(np.isfinite(y)):
                raise ConfigError(
                    f"trajectory.yaw must have one finite angle per waypoint ({w.shape[0]}) [rad], got {self.yaw!r}"
                )
            object.__setattr__(self, "yaw", tuple(float(v) for v in y))
        for name in ("v_max", "a_max", "move_v_max", "move_a_max", "move_j_max", "hover_s"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float))
                or not math.isfinite(v)
                or v < 0
                or (v == 0 and name != "hover_s")
            ):
                raise ConfigError(f"trajectory.{name} must be a number > 0, got {v!r}")
            object.__setattr__(self, name, float(v))


@dataclass(frozen=True)
class LogConfig:
    """What the run writes to ``run.mcap``."""

    mcap: bool = True
    """Write ``run.mcap`` (every visible message, streamed while the run goes)."""
    exclude: tuple[str, ...] = ()
    """Topics left out of the log (e.g. camera images)."""
    truth_cloud: bool = False
    """Log the LiDAR's true hit points (``/truth/point_cloud``, as large as the cloud itself); off by default."""

    def __post_init__(self) -> None:
        if not isinstance(self.mcap, bool):
            raise ConfigError(f"log.mcap must be true or false, got {self.mcap!r}")
        if not isinstance(self.truth_cloud, bool):
            raise ConfigError(f"log.truth_cloud must be true or false, got {self.truth_cloud!r}")
        if isinstance(self.exclude, str) or not all(isinstance(t, str) for t in self.exclude):
            raise ConfigError(f"log.exclude must be a list of topic names, got {self.exclude!r}")
        object.__setattr__(self, "exclude", tuple(self.exclude))


@dataclass(frozen=True)
class PartSpec:
    """One part of a scenario: its kind, the kind's params, and its timing (and, for sensors, topic and
    extrinsic)."""

    kind: str
    params: Any
    latency_s: float = 0.0
    """What the part publishes becomes visible this much later [s]."""
    phase_s: float = 0.0
    """Delay of the part's first run [s]."""
    topic: Topic | None = None
    """Sensors: the topic it publishes on."""
    extrinsic: Transform | None = None
    """Mounted sensors: the sensor's pose in the body frame (under its sensor type's key: T_BI, T_BL, T_BC, ...)."""
    sensor_type: str | None = None
    """Sensors: the name of its kind's :class:`cufund.core.registry.SensorType`."""


def _transform(value: Any, where: str) -> Transform:
    if isinstance(value, Transform):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a mapping {{p: [x, y, z], q: [w, x, y, z]}}, got {value!r}")
    unknown = sorted(set(value) - {"p", "q"})
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in {where}; expected p [m] and q [w, x, y, z]")
    q = value.get("q", (1.0, 0.0, 0.0, 0.0))
    try:
        qa = np.asarray(q, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}.q must be 4 numbers [w, x, y, z], got {q!r}") from None
    if qa.shape == (4,) and np.all(np.isfinite(qa)) and abs(np.linalg.norm(qa) - 1.0) > 1e-6:
        raise ConfigError(
            f"{where}.q must be a unit quaternion [w, x, y, z] (a rotation), got norm {np.linalg.norm(qa):.6g}"
        )
    try:
        return Transform(value.get("p", (0.0, 0.0, 0.0)), q)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{where}: {e}") from None


def _timing(values: dict[str, Any], where: str, own: set[str]) -> tuple[float, float]:
    """The part's latency and phase, unless its kind's params have fields of those names (then they are the
    kind's: e.g. a GNSS receiver models its own latency)."""
    out = []
    for key in ("latency_s", "phase_s"):
        v = values.get(key, 0.0) if key in own else values.pop(key, 0.0)
        if key in own:
            out.append(0.0)
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 or v > 3600:
            raise ConfigError(f"{where}.{key} must be a number of seconds in [0, 3600], got {v!r}")
        out.append(float(v))
    return out[0], out[1]


def parse_part(group: str, value: Any, where: str, sensor_name: str | None = None) -> PartSpec | None:
    """A scenario part from its YAML value (None leaves it out)."""
    if value is None:
        return None
    if isinstance(value, PartSpec):
        lookup(group, value.kind, where)
        return value
    if isinstance(value, str):
        value = {"kind": _SHORTHAND.get((sensor_name or "", value), value)}
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a kind name or a mapping with a 'kind' key, got {type(value).__name__}")
    values = dict(value)
    if "kind" not in values:
        raise ConfigError(f"missing key 'kind' in {where}")
    kind = lookup(group, values.pop("kind"), where)
    latency, phase = _timing(values, where, {f.name for f in dataclasses.fields(kind.params)})
    topic = extrinsic = None
    if group == "sensor":
        assert kind.sensor_type is not None  # a sensor kind names a registered type (Kind and register check)
        stype = sensor_type(kind.sensor_type)
        t = values.pop("topic", f"/sensors/{sensor_name}")
        try:
            topic = Topic(t, stype.message)
        except ValueError as e:
            raise ConfigError(f"{where}.topic: {e}") from None
        key = stype.extrinsic_key
        for other in sorted(extrinsic_keys() - {key}):
            if other in values:
                raise ConfigError(
                    f"{where}.{other}: a {stype.name} sensor's extrinsic is {key or 'not configurable'}, got {other}"
                )
        if key is not None and key in values:
            extrinsic = _transform(values.pop(key), f"{where}.{key}")
    params = kind.parse(values, where)
    return PartSpec(
        kind.name, params, latency, phase, topic, extrinsic, kind.sensor_type if group == "sensor" else None
    )


def part_to_dict(spec: PartSpec | None) -> Any:
    """Plain data that :func:`parse_part` turns back into an equal spec."""
    if spec is None:
        return None
    out: dict[str, Any] = {"kind": spec.kind}
    if spec.latency_s:
        out["latency_s"] = spec.latency_s
    if spec.phase_s:
        out["phase_s"] = spec.phase_s
    if spec.topic is not None:
        out["topic"] = str(spec.topic)
    if spec.extrinsic is not None:
        assert spec.sensor_type is not None  # only a sensor of a type with a mounting key has an extrinsic
        key = sensor_type(spec.sensor_type).extrinsic_key
        assert key is not None
        out[key] = {"p": list(spec.extrinsic.t), "q": list(spec.extrinsic.q)}
    out.update(to_dict(spec.params))
    return out


@dataclass(frozen=True)
class ScenarioConfig:
    """A complete, reproducible run: the pipeline and everything that parametrises it."""

    name: str = "custom"
    vehicle: Any = "cu_astro"
    """A preset name (cu_astro, crazyflie, iris), a mapping of :class:`QuadrotorParams` fields, or ``{preset: NAME,
    ...overrides}``; either mapping may add ``battery: {cells, capacity_mah, ...}`` (off when absent; see
    :mod:`cufund.sensors.power_monitor`)."""
    world: Any = None
    """A world kind (empty, imav2025_tunnel, forest, corridor, file, ...) or null for none (the ground plane of the
    dynamics only)."""
    sensors: Any = None
    """``{NAME: {kind: ..., ...}}``: each sensor publishes on ``/sensors/NAME`` unless given a ``topic``."""
    estimator: Any = None
    """An estimator kind, or null: controllers then fly on ground truth."""
    mapper: Any = None
    perception: Any = None
    """An image detector (kind onnx_detector) or null: none. docs/guides/detection.md."""
    planner: Any = "waypoints"
    controller: Any = "pid"
    mission: Any = None
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    """The reference of the ``waypoints`` planner."""
    rates: RatesConfig = field(default_factory=RatesConfig)
    log: LogConfig = field(default_factory=LogConfig)
    ros2: Any = None
    """The ROS 2 bridge over DDS (``{domain_id, topics, lockstep, lockstep_nodes, realtime, expose, ...}``, the
    ``bridge`` kind ``ros2``; ``cufund ros2 SCENARIO`` adds it); null (default): none. docs/guides/ros2.md."""
    collision_box: tuple[float, float, float] = (0.216, 0.216, 0.095)
    """The vehicle's shape against the world's meshes: a box of these full edge lengths (x, y, z) in the body
    frame [m] (default: CU-Astro's 216 x 216 x 95 mm)."""
    start_p_W: tuple[float, float, float] | None = None
    """Where the vehicle stands at the start, rotors stopped [m] (default: below the first waypoint)."""
    start_yaw: float = 0.0
    """The vehicle's heading at the start [rad] (0: facing east, as by default)."""
    vehicles: Any = None
    """Several vehicles in the world (:mod:`cufund.scenarios.fleet_schema`): ``[{name: uav1, start: {p: [x, y, z],
    yaw: 0}, ...per-vehicle parts}]``; null (default): one vehicle. docs/guides/fleets.md."""
    downwash: Any = None
    """Rotor downwash of a vehicle on those below it, in a fleet (:class:`cufund.worlds.downwash.DownwashConfig`):
    ``true``, or a mapping of its constants; null (default): off."""
    duration: float = 60.0
    """Longest simulated time [s]; the run ends earlier (completed) once the vehicle has landed."""
    faults: Any = None
    """Sensor faults in flight (:mod:`cufund.sensors.faults`): ``{lidar_dropout: {t_start: 12}, ...}`` or a list of
    ``{kind: ..., t_start: ...}``; null: none."""
    realism: Any = None
    """How far the simulated vehicle and sensors are from what flight software is told
    (:class:`cufund.scenarios.realism.RealismConfig`): ``ideal`` (default: every term off), ``realistic``, or
    ``{profile: realistic, imu: {scale_factor_ppm: 3000}, ...}``; see docs/realism.md."""
    failsafe: Any = None
    """The flight stack's failsafes (:class:`cufund.missions.failsafe_params.FailsafeParams`, PX4's names:
    ``{GF_MAX_HOR_DIST: 5, COM_LOW_BAT_ACT: 1, ...}``); absent: the defaults; ``off``: none. docs/guides/failsafes.md."""
    atmosphere: Any = None
    """The air (:class:`cufund.worlds.atmosphere.AtmosphereConfig`): ``{kind: calm | constant | dryden,
    wind_20ft_mps, direction_deg, shear, gusts, grid_file, seed}``; null (default): still air. docs/guides/atmosphere.md."""
    ground_effect: Any = False
    """Ground and ceiling effect on the plant's thrust (:class:`cufund.vehicle.ground_effect.GroundEffectConfig`):
    ``true``, ``false`` (default) or a mapping of its constants."""
    seed: int = 0
    """One seed derives every random stream (sensor noise, LiDAR noise, ...); the same seed repeats a run bit for
    bit."""
    base_dir: str | None = field(default=None, compare=False, repr=False)
    """Where the scenario file lies (relative paths in it resolve from there); not part of the scenario."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"name must be a non-empty string, got {self.name!r}")
        if isinstance(self.vehicle, str):
            if self.vehicle not in _PRESETS:
                raise ConfigError(
                    f"vehicle must be one of {', '.join(_PRESETS)} or a mapping of QuadrotorParams fields, "
                    f"got {self.vehicle!r}"
                )
        elif isinstance(self.vehicle, dict):
            try:
                _vehicle_parts(self.vehicle)
            except (TypeError, ValueError) as e:
                raise ConfigError(f"vehicle: {e}") from None
        else:
            raise ConfigError(f"vehicle must be a preset name or a mapping, got {type(self.vehicle).__name__}")
        for name in _PART_GROUPS:
            object.__setattr__(self, name, parse_part(name, getattr(self, name), name))
        sensors = {} if self.sensors is None else self.sensors
        if not isinstance(sensors, dict):
            raise ConfigError(f"sensors must be a mapping of sensor names to sensors, got {type(sensors).__name__}")
        parsed = {}
        for sname, value in sensors.items():
            if not isinstance(sname, str) or not sname.isidentifier():
                raise ConfigError(
                    f"sensors: a sensor name must be an identifier like imu or lidar_front, got {sname!r}"
                )
            spec = parse_part("sensor", value, f"sensors.{sname}", sensor_name=sname)
            if spec is not None:
                parsed[sname] = spec
        topics = [str(s.topic) for s in parsed.values()]
        dup = sorted({t for t in topics if topics.count(t) > 1})
        if dup:
            raise ConfigError(f"sensors: two sensors publish on {dup[0]}; give one a different topic")
        object.__setattr__(self, "sensors", parsed)
        from .camera_tunnel import camera_only

        camera_only(self, parse_part)  # perception: camera -> no LiDAR, a forward stereo rig
        object.__setattr__(self, "trajectory", nested(TrajectoryConfig, self.trajectory, "trajectory"))
        object.__setattr__(self, "rates", nested(RatesConfig, self.rates, "rates"))
        object.__setattr__(self, "log", nested(LogConfig, self.log, "log"))
        ros2 = {} if self.ros2 is True else (None if self.ros2 is False else self.ros2)
        if isinstance(ros2, dict):
            ros2 = {"kind": "ros2", **ros2}
        object.__setattr__(self, "ros2", parse_part("bridge", ros2, "ros2"))
        object.__setattr__(self, "faults", parse_faults(self.faults))
        object.__setattr__(self, "realism", RealismConfig.parse(self.realism))
        object.__setattr__(self, "failsafe", parse_failsafe(self.failsafe))
        object.__setattr__(self, "atmosphere", AtmosphereConfig.parse(self.atmosphere))
        object.__setattr__(self, "ground_effect", GroundEffectConfig.parse(self.ground_effect))
        object.__setattr__(self, "vehicles", parse_vehicles(self.vehicles))
        if self.vehicles and self.ros2 is not None:  # each vehicle's scenario would get a bridge of its own
            raise ConfigError(
                "ros2: the ROS 2 bridge serves one vehicle under ROS 2's plain names (/imu, /clock, /goal_pose); "
                "a fleet (vehicles:) would publish every vehicle on them and fly every one to each goal"
            )
        object.__setattr__(self, "downwash", DownwashConfig.parse(self.downwash))
        yaw = self.start_yaw
        if (
            isinstance(yaw, bool)
            or not isinstance(yaw, (int, float))
            or not math.isfinite(yaw)
            or abs(yaw) > 2 * math.pi
        ):
            raise ConfigError(f"start_yaw must be a heading in [-2 pi, 2 pi] [rad], got {yaw!r}")
        object.__setattr__(self, "start_yaw", float(yaw))
        try:
            box = np.asarray(self.collision_box, dtype=float)
        except (TypeError, ValueError):
            box = np.zeros(1)
        if box.shape != (3,) or not np.all(np.isfinite(box)) or np.any(box <= 0) or np.any(box > 100):
            raise ConfigError(f"collision_box must be 3 finite lengths in (0, 100] [m], got {self.collision_box!r}")
        object.__setattr__(self, "collision_box", tuple(float(v) for v in box))
        if self.start_p_W is not None:
            try:
                p = np.asarray(self.start_p_W, dtype=float)
            except (TypeError, ValueError):
                p = np.full(1, np.nan)
            if p.shape != (3,) or not np.all(np.isfinite(p)) or p[2] < 0:
                raise ConfigError(f"start_p_W must be 3 finite numbers [m] with z >= 0, got {self.start_p_W!r}")
            object.__setattr__(self, "start_p_W", tuple(float(v) for v in p))
        check_real_fields(self, "scenario", positive=True, unit=" [s]", names=("duration",))
        if self.duration > 1e6:
            raise ConfigError(f"scenario.duration must be at most 1e6 s, got {self.duration!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**63:
            raise ConfigError(f"seed must be an integer in [0, 2^63), got {self.seed!r}")
        check_plausible(self)  # well-formed but surely a mistake: degrees for radians, unreachable speeds

    def vehicle_params(self) -> QuadrotorParams:
        return _PRESETS[self.vehicle]() if isinstance(self.vehicle, str) else _vehicle_parts(self.vehicle)[0]

    def power_system(self) -> PowerSystem | None:
        """``vehicle.battery`` validated (:mod:`cufund.sensors.power_monitor`), or None: no battery (the default)."""
        return None if isinstance(self.vehicle, str) else _vehicle_parts(self.vehicle)[1]

    @classmethod
    def from_dict(cls, data: Any, base_dir: str | Path | None = None) -> ScenarioConfig:
        if isinstance(data, dict) and base_dir is not None:
            data = {**data, "base_dir": str(base_dir)}
        if isinstance(data, dict) and "base_dir" in data and base_dir is None:
            raise ConfigError("unknown key 'base_dir' in scenario")
        return from_dict(cls, data, "scenario")

    def to_dict(self) -> dict[str, Any]:
        """Plain data (for ``config.yaml``) that :meth:`from_dict` turns back into an equal scenario."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "base_dir" or (f.name in _FLEET_KEYS and v == _FLEET_KEYS[f.name]):
                continue  # the fleet keys at their defaults are left out: a single vehicle's config as before
            if f.name == "vehicles":
                out[f.name] = vehicles_to_data(v)
            elif f.name == "downwash":
                out[f.name] = v.to_data()
            elif f.name in _PART_GROUPS:
                out[f.name] = part_to_dict(v)
            elif f.name == "faults":
                out[f.name] = faults_to_data(v)
            elif f.name == "ros2":
                out[f.name] = None if v is None else {k: x for k, x in part_to_dict(v).items() if k != "kind"}
            elif f.name == "realism":
                out[f.name] = v.to_data()
            elif f.name == "sensors":
                out[f.name] = {k: part_to_dict(s) for k, s in v.items()}
            elif dataclasses.is_dataclass(v):
                out[f.name] = to_dict(v)
            elif isinstance(v, tuple):
                out[f.name] = list(v)
            else:
                out[f.name] = v
        return out

    def replace(self, **changes: Any) -> ScenarioConfig:
        return dataclasses.replace(self, **changes)

    def with_overrides(self, overrides: Mapping[str, Any] | Iterable[str]) -> ScenarioConfig:
        """A copy with dotted overrides applied (``{"controller.kind": "geometric"}`` or ``["seed=3"]``)."""
        return ScenarioConfig.from_dict(apply_overrides(self.to_dict(), overrides), self.base_dir)

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (self.to_dict(), self.base_dir))


_FLEET_KEYS: dict[str, Any] = {"start_yaw": 0.0, "vehicles": None, "downwash": None}


def _vehicle_parts(value: dict[str, Any]) -> tuple[QuadrotorParams, PowerSystem | None]:
    """A ``vehicle`` mapping: :class:`QuadrotorParams` fields, or ``preset:`` and overrides of its fields; and an
    optional ``battery:`` (:class:`PowerSystem`)."""
    data = dict(value)
    battery = data.pop("battery", None)
    preset = data.pop("preset", None)
    if preset is not None:
        if not isinstance(preset, str) or preset not in _PRESETS:
            raise ConfigError(f"preset must be one of {', '.join(_PRESETS)}, got {preset!r}")
        data = {**_PRESETS[preset]().to_dict(), **data}
    return QuadrotorParams.from_dict(data), None if battery is None else PowerSystem.parse(battery)


def _rebuild(data: dict[str, Any], base_dir: str | None) -> ScenarioConfig:
    return ScenarioConfig.from_dict(data, base_dir)


def parse_overrides(items: Iterable[str]) -> dict[str, Any]:
    """``["a.b=1", "c=x"]`` as ``{"a.b": 1, "c": "x"}``; values are YAML scalars or flow collections."""
    out: dict[str, Any] = {}
    for item in items:
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(f"--set takes KEY=VALUE with a dotted KEY (e.g. controller.kind=geometric), got {item!r}")
        key, text = item.split("=", 1)
        key = key.strip()
        out[key] = load_yaml_text(text, f"--set {key}") if text.strip() else ""  # bounded; 1e9 is a number
    return out


def apply_overrides(data: dict[str, Any], overrides: Mapping[str, Any] | Iterable[str]) -> dict[str, Any]:
    """``data`` (a scenario as plain data) with each dotted key set. A part given by its bare kind name becomes a
    mapping first (``world.seed=3`` on ``world: forest``); a new key is created, and the validation that follows
    names any key the part does not know."""
    if not isinstance(overrides, Mapping):
        overrides = parse_overrides(overrides)
    out = _deep_copy(data)
    for key, value in overrides.items():
        if not isinstance(key, str) or not key or any(not p for p in key.split(".")):
            raise ConfigError(f"an override key must be a dotted name like controller.kind, got {key!r}")
        parts = key.split(".")
        node = out
        for depth, p in enumerate(parts[:-1]):
            child = node.get(p)
            if isinstance(child, str) and depth == 0 and p == "realism":
                child = {"profile": child}  # realism.imu.x=1 on realism: realistic
            elif isinstance(child, str) and depth == 0 and p == "vehicle":
                child = {"preset": child}  # vehicle.battery.cells=4 on vehicle: cu_astro
            elif isinstance(child, str) and (depth > 0 or p in _PART_GROUPS):
                child = {"kind": _SHORTHAND.get((p, child), child)}
            elif child is None:
                child = {}
            elif not isinstance(child, dict):
                raise ConfigError(f"override {key}: {'.'.join(parts[: depth + 1])} is {child!r}, not a mapping")
            node[p] = child
            node = child
        node[parts[-1]] = value
    return out


def _deep_copy(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _deep_copy(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_deep_copy(v) for v in x]
    return x


def _scenario_dir() -> Path:
    return Path(__file__).resolve().parent / "builtin"


def available_scenarios(whole: bool = False) -> dict[str, str]:
    """Built-in scenario names and their descriptions: the YAML's first comment line, or with ``whole`` every
    comment line before the first key, joined into one paragraph."""
    out = {}
    for p in sorted(_scenario_dir().glob("*.yaml")):
        lines = p.read_text(encoding="utf-8").splitlines()
        head = [line.lstrip("# ").strip() for line in (lines if whole else lines[:1])]
        end = next((i for i, line in enumerate(lines) if not line.startswith("#")), len(lines))
        out[p.stem] = " ".join(h for h in head[: end if whole else 1] if h)
    return out


def load_scenario(name_or_path: str | Path, overrides: Mapping[str, Any] | Iterable[str] = ()) -> ScenarioConfig:
    """A built-in scenario by name (see :func:`available_scenarios`) or a YAML file, with dotted ``overrides``."""
    p = Path(name_or_path)
    if not p.suffix and not p.exists():
        p = _scenario_dir() / f"{name_or_path}.yaml"
        if not p.exists():
            raise ConfigError(f"unknown scenario {str(name_or_path)!r}; built-in: {', '.join(available_scenarios())}")
    data = load_yaml(p)
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: a scenario must be a mapping of keys to values, got {type(data).__name__}")
    return ScenarioConfig.from_dict(apply_overrides(data, overrides), base_dir=p.resolve().parent)

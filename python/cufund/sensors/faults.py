"""Sensor faults in flight, as scenario options (``faults:`` in a scenario).

Each fault acts on what one sensor publishes, from a start time ``t_start`` [s] of simulated time:

- ``lidar_dropout``: the LiDAR publishes nothing for ``duration`` s (a frame whose publication falls in
  [t_start, t_start + duration) is lost).
- ``imu_bias_step``: from ``t_start`` on (measurement stamp), the accelerometer reads ``accel`` [m/s^2] more and
  the gyroscope ``gyro`` [rad/s] more, in the IMU's own frame (a bias jump).
- ``lidar_degraded``: from ``t_start`` (for ``duration`` s, or for good when null) each frame keeps a random
  ``fraction`` of its points and each kept range gets Gaussian noise of ``noise_m`` [m] (1 sigma), the point
  moved along its ray.

Written as a map ``{lidar_dropout: {t_start: 12}, imu_bias_step: {t_start: 20, gyro: [0, 0, 0.05]}}`` (one fault
of a kind; overridable as ``--set faults.lidar_dropout.t_start=12``) or a list ``[{kind: lidar_dropout,
t_start: 12}, ...]`` (several of a kind). Each fault takes ``sensor``: the sensor's name under ``sensors``
(default: the only sensor of its type). The faults' random streams derive from the scenario seed (a run repeats
bit for bit). The simulator injects them by wrapping the sensor's component (:class:`FaultySensor`): the sensor
model itself is untouched, so the same seed gives the same clean measurements with and without faults.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.components import Component
from cufund.core.config import ConfigError, from_dict, to_dict, vector3
from cufund.core.messages import Imu, PointCloud

__all__ = [
    "FAULT_KINDS",
    "FaultySensor",
    "ImuBiasStep",
    "LidarDegraded",
    "LidarDropout",
    "faults_to_data",
    "fault_summary",
    "inject_faults",
    "parse_faults",
]


def _time(where: str, value: Any, positive: bool = False) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value < 0
        or (positive and value == 0)
        or value > 1e6
    ):
        raise ConfigError(f"{where} must be a number of seconds in {'(0' if positive else '[0'}, 1e6], got {value!r}")
    return float(value)


def _sensor(where: str, value: Any) -> str:
    if not isinstance(value, str) or (value and not value.isidentifier()):
        raise ConfigError(f"{where} must be a sensor name under sensors (or '' for the only one), got {value!r}")
    return value


@dataclass(frozen=True)
class LidarDropout:
    """No LiDAR frames for ``duration`` seconds."""

    t_start: float
    """Start of the outage (simulated time) [s]."""
    duration: float = 1.0
    """Length of the outage [s]."""
    sensor: str = ""
    """The LiDAR's name under ``sensors`` ('' : the only LiDAR)."""

    kind = "lidar_dropout"
    sensor_type = "lidar"

    def __post_init__(self) -> None:
        object.__setattr__(self, "t_start", _time(f"faults.{self.kind}.t_start", self.t_start))
        object.__setattr__(self, "duration", _time(f"faults.{self.kind}.duration", self.duration, positive=True))
        _sensor(f"faults.{self.kind}.sensor", self.sensor)


@dataclass(frozen=True)
class ImuBiasStep:
    """The IMU's biases jump at ``t_start`` and stay."""

    t_start: float
    """When the biases jump (measurement stamp) [s]."""
    accel: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Accelerometer bias step, IMU frame [m/s^2]."""
    gyro: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Gyroscope bias step, IMU frame [rad/s]."""
    sensor: str = ""
    """The IMU's name under ``sensors`` ('' : the only IMU)."""

    kind = "imu_bias_step"
    sensor_type = "imu"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", _time(f"{w}.t_start", self.t_start))
        a = vector3(f"{w}.accel", self.accel, " [m/s^2]", finite=True)
        g = vector3(f"{w}.gyro", self.gyro, " [rad/s]", finite=True)
        if max(map(abs, a)) > 100 or max(map(abs, g)) > 10:
            raise ConfigError(
                f"{w}: a bias step must be at most 100 m/s^2 (accel) and 10 rad/s (gyro) per axis, "
                f"got accel {a}, gyro {g}"
            )
        object.__setattr__(self, "accel", a)
        object.__setattr__(self, "gyro", g)
        _sensor(f"{w}.sensor", self.sensor)


@dataclass(frozen=True)
class LidarDegraded:
    """Fewer and noisier LiDAR returns from ``t_start``."""

    t_start: float
    """Start of the degradation (simulated time) [s]."""
    fraction: float = 0.5
    """Share of each frame's points kept, in (0, 1]."""
    noise_m: float = 0.05
    """Gaussian range noise added to every kept point, 1 sigma [m]."""
    duration: float | None = None
    """Length of the degradation [s]; null: to the end of the run."""
    sensor: str = ""
    """The LiDAR's name under ``sensors`` ('' : the only LiDAR)."""

    kind = "lidar_degraded"
    sensor_type = "lidar"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", _time(f"{w}.t_start", self.t_start))
        if self.duration is not None:
            object.__setattr__(self, "duration", _time(f"{w}.duration", self.duration, positive=True))
        f = self.fraction
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not 0 < f <= 1:
            raise ConfigError(f"{w}.fraction must be a share of points in (0, 1], got {f!r}")
        n = self.noise_m
        if isinstance(n, bool) or not isinstance(n, (int, float)) or not math.isfinite(n) or not 0 <= n <= 10:
            raise ConfigError(f"{w}.noise_m must be a range noise in [0, 10] m, got {n!r}")
        object.__setattr__(self, "fraction", float(f))
        object.__setattr__(self, "noise_m", float(n))
        _sensor(f"{w}.sensor", self.sensor)


FAULT_KINDS: dict[str, type] = {c.kind: c for c in (LidarDropout, ImuBiasStep, LidarDegraded)}
"""Fault kind name -> its params dataclass."""

Fault = LidarDropout | ImuBiasStep | LidarDegraded


def _one(kind: Any, params: Any, where: str) -> Any:
    if isinstance(params, tuple(FAULT_KINDS.values())):
        return params
    cls = FAULT_KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ConfigError(f"{where}: unknown fault kind {kind!r}; expected one of: {', '.join(FAULT_KINDS)}")
    return from_dict(cls, params, f"{where}")


def parse_faults(value: Any) -> tuple[Any, ...]:
    """The faults of a scenario's ``faults:`` value (null, a map ``{kind: params or [params, ...]}`` or a list
    of ``{kind: ..., ...params}``), validated (:class:`cufund.ConfigError` naming the key otherwise)."""
    if value is None:
        return ()
    out = []
    if isinstance(value, dict):
        for kind, params in value.items():
            for i, p in enumerate(params if isinstance(params, (list, tuple)) else [params]):
                out.append(_one(kind, p, f"faults.{kind}" + (f"[{i}]" if isinstance(params, (list, tuple)) else "")))
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            if isinstance(item, tuple(FAULT_KINDS.values())):
                out.append(item)
                continue
            if not isinstance(item, dict) or "kind" not in item:
                raise ConfigError(
                    f"faults[{i}] must be a mapping with a 'kind' key ({', '.join(FAULT_KINDS)}), got {item!r}"
                )
            params = dict(item)
            out.append(_one(params.pop("kind"), params, f"faults[{i}]"))
    else:
        raise ConfigError(
            "faults must be a map {kind: {t_start: ..., ...}} or a list of {kind: ..., t_start: ...}, "
            f"got {type(value).__name__}"
        )
    return tuple(out)


def faults_to_data(faults: tuple[Any, ...]) -> Any:
    """Plain data :func:`parse_faults` turns back into equal faults: a map when each kind occurs once (so dotted
    overrides reach it), else a list; None for no faults."""
    if not faults:
        return None
    kinds = [f.kind for f in faults]
    if len(set(kinds)) == len(kinds):
        return {f.kind: _plain(f) for f in faults}
    return [{"kind": f.kind, **_plain(f)} for f in faults]


def _plain(fault: Any) -> dict[str, Any]:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in to_dict(fault).items()}


# ---------------------------------------------------------------------------------------------- injection
class _Active:
    """A fault at run time: ``apply(now, msg) -> msg or None`` with its own seeded stream."""

    def __init__(self, fault: Any, seed: int) -> None:
        self.fault, self.seed = fault, seed
        self.reset()

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.affected = 0
        """Messages dropped or altered so far in this run."""

    def apply(self, now: float, msg: Any) -> Any:
        f = self.fault
        if isinstance(f, LidarDropout):
            if f.t_start <= now < f.t_start + f.duration:
                self.affected += 1
                return None
            return msg
        if isinstance(f, ImuBiasStep):
            if msg.t < f.t_start:
                return msg
            self.affected += 1
            return Imu(msg.t, msg.f_I + np.asarray(f.accel), msg.w_I + np.asarray(f.gyro))
        if now < f.t_start or (f.duration is not None and now >= f.t_start + f.duration):
            return msg
        self.affected += 1
        return degrade(msg, f.fraction, f.noise_m, self.rng)


def degrade(cloud: PointCloud, fraction: float, noise_m: float, rng: np.random.Generator) -> PointCloud:
    """``cloud`` with round(fraction * N) of its points, chosen at random (kept in order), each range plus
    N(0, noise_m^2) and its point moved along its ray (ranges stay >= 1 mm)."""
    n = len(cloud)
    keep = int(round(fraction * n))
    idx = np.sort(rng.choice(n, size=keep, replace=False)) if keep < n else np.arange(n)
    r = cloud.ranges[idx]
    r_new = np.maximum(r + rng.normal(0.0, noise_m, keep), 1e-3) if noise_m > 0 else r.copy()
    scale = np.divide(r_new, r, out=np.ones_like(r), where=r > 0)
    pts = (cloud.points_L[idx] * scale[:, None]).astype(np.float32)
    return PointCloud(cloud.t, cloud.dt[idx], pts, r_new, cloud.intensity[idx], cloud.channel[idx], cloud.frame)


class _FaultBus:
    """A sensor's bus handle that passes what it publishes on faulty topics through the faults."""

    __slots__ = ("_view", "_faults")

    def __init__(self, view: Any, faults: dict[str, list[_Active]]) -> None:
        self._view, self._faults = view, faults

    def __getattr__(self, name: str) -> Any:
        return getattr(self._view, name)

    def latest(self, topic: str) -> Any:
        return self._view.latest(topic)

    get = latest

    def publish(self, topic: str, message: Any) -> None:
        faults = self._faults.get(str(topic))
        if faults:
            now = self._view.now
            for f in faults:
                message = f.apply(now, message)
                if message is None:
                    return
        self._view.publish(topic, message)


def _delegate(name: str) -> property:
    return property(lambda self: getattr(self.inner, name), lambda self, v: setattr(self.inner, name, v))


class FaultySensor(Component):
    """A sensor component whose publications on some topics pass through faults first. It runs, is named and
    timed exactly as the sensor it wraps."""

    name = _delegate("name")
    rate_hz = _delegate("rate_hz")
    phase_s = _delegate("phase_s")
    latency_s = _delegate("latency_s")
    inputs = _delegate("inputs")
    optional_inputs = _delegate("optional_inputs")
    outputs = _delegate("outputs")
    reads_truth = _delegate("reads_truth")

    def __init__(self, inner: Component, faults: dict[str, list[_Active]]) -> None:
        self.inner, self.faults = inner, faults
        self._bus: _FaultBus | None = None

    def reset(self) -> None:
        for fs in self.faults.values():
            for f in fs:
                f.reset()
        self.inner.reset()

    def setup(self, bus: Any) -> None:
        self._bus = _FaultBus(bus, self.faults)
        self.inner.setup(self._bus)  # type: ignore[arg-type]  # duck-types the BusView it wraps

    def step(self, t: float, bus: Any) -> None:
        if self._bus is None or self._bus._view is not bus:
            self._bus = _FaultBus(bus, self.faults)
        self.inner.step(t, self._bus)  # type: ignore[arg-type]  # duck-types the BusView it wraps

    def __getattr__(self, name: str) -> Any:  # the wrapped sensor's own attributes (lidar, model, topic, ...)
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)


def inject_faults(
    faults: tuple[Any, ...], sensors: dict[str, Any], components: list[Component], seed_for: Callable[[str], int]
) -> list[Component]:
    """``components`` (the sensors' components) with those publishing a faulty sensor's topic wrapped in a
    :class:`FaultySensor`. ``sensors``: the scenario's ``{name: PartSpec}``; ``seed_for(where)``: the scenario's
    per-part seeds."""
    if not faults:
        return components
    by_topic: dict[str, list[_Active]] = {}
    for i, f in enumerate(faults):
        where = f"faults.{f.kind}"
        if f.sensor:
            spec = sensors.get(f.sensor)
            if spec is None or spec.sensor_type != f.sensor_type:
                raise ConfigError(f"{where}.sensor: no {f.sensor_type} sensor named {f.sensor!r} in sensors")
        else:
            found = [s for s in sensors.values() if s.sensor_type == f.sensor_type]
            if len(found) != 1:
                raise ConfigError(
                    f"{where} needs {'a' if not found else 'one'} {f.sensor_type} sensor"
                    f"{'' if not found else ' (several: name one in sensor)'}; "
                    f"the scenario has {len(found)}"
                )
            spec = found[0]
        by_topic.setdefault(str(spec.topic), []).append(_Active(f, seed_for(f"faults[{i}].{f.kind}")))
    out = []
    for c in components:
        mine = {t: by_topic[t] for t in (str(o) for o in c.outputs) if t in by_topic}
        out.append(FaultySensor(c, mine) if mine else c)
    return out


def fault_summary(faults: tuple[Any, ...]) -> list[dict[str, Any]]:
    """The faults as plain records for ``metrics.json``."""
    return [{"kind": f.kind, **_plain(f)} for f in faults]

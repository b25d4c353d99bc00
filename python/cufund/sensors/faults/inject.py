"""Injecting the faults into a run: the sensors' components wrapped so that what they publish passes through their
faults, and the plant's faults as a component acting on the vehicle."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from cufund.core.components import Component
from cufund.core.config import ConfigError

from .base import FaultRun, SensorFault
from .plant import plant_faults

__all__ = ["FaultySensor", "inject_faults"]


class _FaultBus:
    """A sensor's bus handle that passes what it publishes on faulty topics through the faults."""

    __slots__ = ("_view", "_faults")

    def __init__(self, view: Any, faults: dict[str, list[FaultRun]]) -> None:
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

    def __init__(self, inner: Component, faults: dict[str, list[FaultRun]]) -> None:
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
    faults: tuple[Any, ...],
    sensors: dict[str, Any],
    components: list[Component],
    seed_for: Callable[[str], int],
    plant: Any = None,
    physics_rate_hz: float = 1000.0,
) -> list[Component]:
    """``components`` (the sensors' components) with those publishing a faulty sensor's topic wrapped in a
    :class:`FaultySensor`, followed by the component applying the plant's faults to ``plant`` (when there are
    some: :mod:`.plant`). ``sensors``: the scenario's ``{name: PartSpec}``; ``seed_for(where)``: the scenario's
    per-part seeds (fault i draws from ``seed_for("faults[i].<kind>")``)."""
    if not faults:
        return components
    by_topic: dict[str, list[FaultRun]] = {}
    for i, f in enumerate(faults):
        if not isinstance(f, SensorFault):
            continue
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
        by_topic.setdefault(str(spec.topic), []).append(FaultRun(f, seed_for(f"faults[{i}].{f.kind}"), spec.params))
    out: list[Component] = []
    for c in components:
        mine = {t: by_topic[t] for t in (str(o) for o in c.outputs) if t in by_topic}
        out.append(FaultySensor(c, mine) if mine else c)
    return out + plant_faults(faults, plant, physics_rate_hz, seed_for)

"""The scenario's ``vehicles:`` key: several vehicles in one world (docs/guides/fleets.md).

Each entry is ``{name: uav1, start: {p: [x, y, z], yaw: rad}, ...overrides}``; the overrides replace the
scenario's top-level part of the same key for that vehicle (a whole part, not merged into it): any of
:data:`OVERRIDABLE`. The world, rates, duration, atmosphere and seed are the fleet's. Validated here as plain data; each vehicle's own scenario is made (and validated as any scenario) by
:func:`cufund.scenarios.fleet.vehicle_scenario`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from cufund.core.config import ConfigError

__all__ = ["OVERRIDABLE", "VehicleSpec", "parse_vehicles", "vehicles_to_data"]

OVERRIDABLE = (
    "vehicle",
    "sensors",
    "estimator",
    "mapper",
    "perception",
    "planner",
    "controller",
    "mission",
    "trajectory",
    "failsafe",
    "faults",
    "realism",
    "collision_box",
    "ground_effect",
)
"""The scenario keys a vehicle entry may set for itself."""

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class VehicleSpec:
    """One vehicle of a fleet."""

    name: str
    """Its name: its topics' namespace (``/uav1/sensors/imu``) and the key of its random streams' seed."""
    start_p_W: tuple[float, float, float] | None = None
    """Where it stands at the start [m] (null: below its first waypoint, as a single vehicle)."""
    start_yaw: float = 0.0
    """Its heading at the start [rad] (ENU: 0 faces east)."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Scenario keys it sets for itself (plain data, see :data:`OVERRIDABLE`)."""


def _number(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigError(f"{where} must be a finite number, got {v!r}")
    return float(v)


def _one(value: Any, i: int) -> VehicleSpec:
    where = f"vehicles[{i}]"
    if isinstance(value, VehicleSpec):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a mapping {{name: uav1, start: {{p: [x, y, z], yaw: 0}}, ...}}")
    data = dict(value)
    name = data.pop("name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        raise ConfigError(f"{where}.name must be a name like uav1 (a letter, then letters, digits, _), got {name!r}")
    where = f"vehicles.{name}"
    start = data.pop("start", None) or {}
    if not isinstance(start, dict):
        raise ConfigError(f"{where}.start must be a mapping {{p: [x, y, z], yaw: rad}}, got {start!r}")
    unknown = sorted(set(start) - {"p", "yaw"})
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in {where}.start; expected p [m] and yaw [rad]")
    p = start.get("p")
    start_p: tuple[float, float, float] | None = None
    if p is not None:
        if not isinstance(p, (list, tuple)) or len(p) != 3:
            raise ConfigError(f"{where}.start.p must be 3 numbers [x, y, z] [m], got {p!r}")
        start_p = (
            _number(p[0], f"{where}.start.p"),
            _number(p[1], f"{where}.start.p"),
            _number(p[2], f"{where}.start.p"),
        )
        if start_p[2] < 0:
            raise ConfigError(f"{where}.start.p must have z >= 0 (on or above the ground), got {p!r}")
    yaw = _number(start.get("yaw", 0.0), f"{where}.start.yaw")
    if abs(yaw) > 2 * math.pi:
        raise ConfigError(f"{where}.start.yaw must be in [-2 pi, 2 pi] [rad] (radians, not degrees), got {yaw!r}")
    unknown = sorted(set(data) - set(OVERRIDABLE))
    if unknown:
        raise ConfigError(
            f"unknown key {unknown[0]!r} in {where}; a vehicle takes name, start and any of: {', '.join(OVERRIDABLE)}"
        )
    return VehicleSpec(name, start_p, yaw, data)


def parse_vehicles(value: Any) -> tuple[VehicleSpec, ...] | None:
    """The ``vehicles:`` list validated (null or absent: a single-vehicle scenario)."""
    if value is None:
        return None
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise ConfigError(f"vehicles must be a list of vehicles {{name: uav1, start: {{p: [x, y, z]}}}}, got {value!r}")
    if not value:
        raise ConfigError("vehicles must list at least one vehicle (or be left out for a single-vehicle scenario)")
    out = tuple(_one(v, i) for i, v in enumerate(value))
    names = [v.name for v in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"vehicles: two vehicles are named {dup[0]!r}; each needs its own name")
    return out


def vehicles_to_data(vehicles: tuple[VehicleSpec, ...] | None) -> Any:
    """Plain data that :func:`parse_vehicles` turns back into equal specs."""
    if vehicles is None:
        return None
    out = []
    for v in vehicles:
        start: dict[str, Any] = {}
        if v.start_p_W is not None:
            start["p"] = list(v.start_p_W)
        if v.start_yaw:
            start["yaw"] = v.start_yaw
        item: dict[str, Any] = {"name": v.name}
        if start:
            item["start"] = start
        item.update(v.overrides)
        out.append(item)
    return out

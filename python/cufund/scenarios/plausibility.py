"""Plausibility checks on a validated scenario: values that are well-formed but surely a mistake.

A scenario may be valid field by field and still say something no one meant. Three mistakes are refused at load
(:class:`ConfigError` naming the field, so ``cufund run`` exits 2 before anything runs):

- **An angle in degrees where radians are documented.** Every field whose attribute docstring gives its unit as
  ``[rad]`` (``trajectory.yaw``, ``controller.position.tilt_max``, ``estimator.pad_yaw``, ``*.attitude_sigma_rad``,
  a commander's ``yaw``, ...), or, undocumented, whose name says radians (``*_rad``, ``yaw``), must lie in
  [-2 pi, 2 pi]: ``trajectory.yaw: [0, 90]`` was flown as 90 rad (a 117 degree yaw). Fields documented ``[deg]``
  must lie within a full turn, [-360, 360].
- **A speed or an acceleration limit the vehicle cannot reach.** Limits are the fields documented ``[m/s]`` whose
  name says a limit of the vehicle's motion (``*v_max*``, ``*vel_max*``, ``*_speed``) and the fields documented
  ``[m/s^2]`` whose name ends in ``_max`` (``a_max``, ``move_a_max``, ``i_max``). Bounds from the scenario's vehicle
  (:func:`reach`): acceleration at most ``sqrt((T_max / m)^2 + g^2)``, the largest ``|a|`` that thrust up to
  ``T_max`` at a tilt up to 90 degrees gives against gravity (CU-Astro: thrust-to-weight 2.5, 26.4 m/s^2); speed at
  most the drag-limited terminal speed in level flight (all the thrust left over from carrying the weight pushing
  against the smallest horizontal body drag and the rotor drag at hover speed, so an upper bound) and at most
  :data:`SPEED_CEILING` (100 m/s) for vehicles without a drag model, beyond which the simulator's models
  (incompressible drag, hover rotor model) say nothing true. CU-Astro: 37.8 m/s. ``v_max: 1500`` is refused.
- **A key given twice in a YAML file** is refused by the loader itself (:class:`cufund.core.config.CufundLoader`).

The checks walk the scenario's dataclasses (every part's params and every section, nested ones, lists of them) and
read units from the attribute docstrings, so a field added with a documented ``[rad]`` unit is checked without
being listed here.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import math
import re
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np

from cufund.core.config import ConfigError
from cufund.vehicle.params import QuadrotorParams

__all__ = ["SPEED_CEILING", "Reach", "check_plausible", "checked_fields", "field_units", "reach"]

SPEED_CEILING = 100.0
"""The largest speed limit accepted for any vehicle [m/s] (360 km/h): beyond it the simulator's models are not
valid, whatever the vehicle's drag model says."""

_UNIT = re.compile(r"\[([^\[\]]+)\]")
_ACCEL_UNITS = {"m/s^2", "m/s2", "m/s²", "m s^-2"}


@dataclasses.dataclass(frozen=True)
class Reach:
    """What a vehicle can reach, as bounds for plausibility (generous: never below the true reach)."""

    acceleration: float
    """Largest |a| [m/s^2]: ``sqrt((T_max / m)^2 + g^2)``."""
    speed: float
    """Largest speed [m/s]: the drag-limited terminal speed in level flight, at most :data:`SPEED_CEILING`."""
    thrust_to_weight: float
    """``T_max / (m g)``."""


def reach(vehicle: QuadrotorParams) -> Reach:
    """The bounds of :class:`Reach` for ``vehicle`` (see the module's docstring)."""
    weight = vehicle.mass * vehicle.gravity
    t_max = vehicle.max_thrust
    a_thrust = t_max / vehicle.mass
    t_horizontal = math.sqrt(max(t_max * t_max - weight * weight, 0.0))
    c_quadratic = float(min(vehicle.body_drag[0], vehicle.body_drag[1]))  # N/(m/s)^2, the least frontal drag
    c_linear = 4.0 * vehicle.hover_rotor_speed * vehicle.rotor_drag_xy  # N/(m/s), the rotors at hover speed
    if c_quadratic > 0:
        v = (-c_linear + math.sqrt(c_linear * c_linear + 4.0 * c_quadratic * t_horizontal)) / (2.0 * c_quadratic)
    elif c_linear > 0:
        v = t_horizontal / c_linear
    else:
        v = math.inf
    return Reach(math.hypot(a_thrust, vehicle.gravity), min(v, SPEED_CEILING), t_max / weight)


@functools.cache
def _module_units(module: str) -> dict[str, dict[str, str]]:
    """Every class of ``module`` by qualified name: its fields' documented units (one parse per module)."""
    try:
        tree = ast.parse(inspect.getsource(sys.modules[module]))
    except (KeyError, OSError, TypeError, SyntaxError):
        return {}
    out: dict[str, dict[str, str]] = {}
    stack: list[tuple[ast.AST, str]] = [(tree, "")]
    while stack:
        parent, prefix = stack.pop()
        for cls in (n for n in ast.iter_child_nodes(parent) if isinstance(n, ast.ClassDef)):
            name = f"{prefix}{cls.name}"
            stack.append((cls, f"{name}."))
            units = out.setdefault(name, {})
            for node, after in zip(cls.body, [*cls.body[1:], None], strict=True):
                if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
                    continue
                if (
                    isinstance(after, ast.Expr)
                    and isinstance(after.value, ast.Constant)
                    and isinstance(after.value.value, str)
                ):
                    unit = _UNIT.search(after.value.value)
                    units[node.target.id] = unit.group(1).strip() if unit else ""
    return out


@functools.cache
def field_units(cls: type) -> dict[str, str]:
    """The unit each field of dataclass ``cls`` documents: the first ``[...]`` of its attribute docstring (the
    string literal after the field; base classes included; "" when it gives none). Fields without a docstring are
    absent."""
    out: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if dataclasses.is_dataclass(klass):
            out.update(_module_units(klass.__module__).get(klass.__qualname__, {}))
    return out


def _kind_of(name: str, unit: str) -> str | None:
    """'rad', 'deg', 'speed', 'acceleration' or None for a field ``name`` documented in ``unit``."""
    if not unit:  # undocumented: the name tells (a commander's MissionItem.yaw)
        unit = "rad" if name.endswith("_rad") or name == "yaw" else "deg" if name.endswith("_deg") else ""
    if unit in ("rad", "deg"):
        return unit
    if unit == "m/s" and ("v_max" in name or "vel_max" in name or name.endswith("_speed") or name == "speed"):
        return "speed"
    if unit in _ACCEL_UNITS and name.endswith("_max"):
        return "acceleration"
    return None


def _numbers(value: Any, where: str) -> Iterator[tuple[str, float]]:
    """The real numbers in ``value`` (a number, or a list/tuple/array of them) with their paths."""
    if isinstance(value, bool) or value is None:
        return
    if isinstance(value, (int, float, np.integer, np.floating)):
        yield where, float(value)
    elif isinstance(value, (tuple, list, np.ndarray)):
        for i, v in enumerate(value):
            yield from _numbers(v, f"{where}[{i}]")


def _fields(obj: Any, where: str) -> Iterator[tuple[str, str, Any]]:
    """(path, kind, value) of every checked field in ``obj`` and the dataclasses nested in it."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        units = field_units(type(obj))
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            path = f"{where}.{f.name}" if where else f.name
            kind = _kind_of(f.name, units.get(f.name, ""))
            if kind is not None:
                yield path, kind, value
            yield from _fields(value, path)
    elif isinstance(obj, (tuple, list)):
        for i, v in enumerate(obj):
            yield from _fields(v, f"{where}[{i}]")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            yield from _fields(v, f"{where}.{k}" if where else str(k))


def _parts(config: Any) -> Iterator[tuple[str, Any]]:
    """(path, object) of what a scenario configures: each part's params (sensors by name) and every section held as
    a dataclass (trajectory, rates, realism, ...); the vehicle is the reference, not a limit."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if isinstance(value, dict):  # sensors: {name: PartSpec}
            for name, spec in value.items():
                yield f"{f.name}.{name}", getattr(spec, "params", spec)
        elif hasattr(value, "params") and hasattr(value, "kind"):  # a PartSpec
            yield f.name, value.params
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            yield f.name, value


def checked_fields(config: Any) -> list[tuple[str, str]]:
    """(dotted path, 'rad' | 'deg' | 'speed' | 'acceleration') of every field of the validated ScenarioConfig
    ``config`` that :func:`check_plausible` checks."""
    return [(path, kind) for root, obj in _parts(config) for path, kind, _ in _fields(obj, root)]


def check_plausible(config: Any) -> None:
    """Raises :class:`ConfigError` naming the first field of the validated ScenarioConfig ``config`` whose value is
    surely a mistake (see the module's docstring)."""
    bounds: Reach | None = None
    for root, obj in _parts(config):
        for path, kind, value in _fields(obj, root):
            for name, v in _numbers(value, path):
                if not math.isfinite(v):
                    continue
                if kind == "rad" and abs(v) > 2.0 * math.pi:
                    raise ConfigError(
                        f"{name} = {v:g} is an angle in radians, outside [-2 pi, 2 pi]: did you mean degrees? "
                        f"({v:g} deg is {math.radians(v):.4g} rad)"
                    )
                if kind == "deg" and abs(v) > 360.0:
                    raise ConfigError(f"{name} = {v:g} is an angle in degrees, beyond a full turn [-360, 360]")
                if kind in ("speed", "acceleration"):
                    bounds = bounds or reach(config.vehicle_params())
                    if bounds.thrust_to_weight <= 1.0:
                        continue  # a vehicle that cannot hover: no bound from its thrust
                    vehicle = config.vehicle if isinstance(config.vehicle, str) else "the scenario's vehicle"
                    if kind == "speed" and v > bounds.speed:
                        raise ConfigError(
                            f"{name} = {v:g} m/s is beyond what {vehicle} can reach: at most {bounds.speed:.3g} m/s "
                            f"(its drag-limited top speed, capped at {SPEED_CEILING:g} m/s; "
                            "see cufund.scenarios.plausibility)"
                        )
                    if kind == "acceleration" and v > bounds.acceleration:
                        raise ConfigError(
                            f"{name} = {v:g} m/s^2 is beyond what {vehicle}'s thrust can give: at most "
                            f"{bounds.acceleration:.3g} m/s^2 (thrust-to-weight {bounds.thrust_to_weight:.3g}; "
                            "see cufund.scenarios.plausibility)"
                        )

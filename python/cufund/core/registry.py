"""The registry of scenario kinds: each part of a scenario (world, sensors, estimator, mapper, planner,
controller, mission) names a ``kind`` that maps to a factory and a typed, frozen params dataclass; each sensor
kind names a :class:`SensorType`, registered once, that declares the message its topic carries and the key its
mounting is given under.

Users add kinds and sensor types from Python with :func:`register`, or from an installed package through the
entry-point group ``cufund.kinds``: each entry point names a :class:`Kind` or :class:`SensorType`, an iterable of
them, or a function returning either::

    [project.entry-points."cufund.kinds"]
    my_ekf = "my_package.cufund_kinds:KINDS"

A kind's ``build(params, ctx)`` reads the scenario through ``ctx``, a
:class:`cufund.core.build_context.BuildContext` (the scenario, vehicle, world, sensors, the part and its seed),
and contributes to the run only through its declared calls (``set_reference``, ``set_done_condition``,
``set_commander``, ``add_metric_hook``, ``add_output_hook``)::

    from cufund.core.build_context import BuildContext
    from cufund.core.registry import Kind, SensorType, register

    register(SensorType("radar", RadarScan, "T_BR"))  # a new sensor type: its message and its mounting key
    def build_radar(p: RadarParams, ctx: BuildContext) -> list[Component]:
        return [RadarSensor(p, ctx.part.extrinsic, ctx.seed, ctx.part.topic)]
    register(Kind("sensor", "my_radar", RadarParams, build_radar, sensor_type="radar"))
"""

from __future__ import annotations

import dataclasses
import re
import types
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, overload

from .build_context import BuildContext
from .errors import ConfigError

__all__ = [
    "ENTRY_POINT_GROUP",
    "GROUPS",
    "Kind",
    "SensorType",
    "available",
    "extrinsic_keys",
    "load_plugins",
    "lookup",
    "register",
    "sensor_type",
    "sensor_types",
    "unregister",
]

ENTRY_POINT_GROUP = "cufund.kinds"
GROUPS = ("world", "sensor", "estimator", "mapper", "perception", "planner", "controller", "mission", "bridge")
"""The parts of a scenario that take a ``kind``."""

_EXTRINSIC_KEY = re.compile(r"T_B[A-Za-z][A-Za-z0-9]*")


@dataclass(frozen=True)
class SensorType:
    """A type of sensor a scenario may carry (imu, lidar, ...), registered once for all its kinds: the message its
    topic carries and, for a mounted sensor, the key its mounting is given under in a scenario."""

    name: str
    """What kinds (``Kind.sensor_type``) and parts (``ctx.sensor_of_type``) call it."""
    message: type
    """The message class every sensor of this type publishes (its topic is typed with it)."""
    extrinsic_key: str | None = None
    """The scenario key of its mounting, ``T_B<X>`` (the sensor frame X's pose in the body frame, ``{p, q}``), e.g.
    ``T_BL`` for a LiDAR; None: not configurable (the sensor is read along the body axes)."""
    doc: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"SensorType.name must be an identifier like imu or radar, got {self.name!r}")
        if not isinstance(self.message, type):
            raise ValueError(f"SensorType.message must be a message class, got {self.message!r}")
        key = self.extrinsic_key
        if key is not None and (not isinstance(key, str) or not _EXTRINSIC_KEY.fullmatch(key)):
            raise ValueError(
                f"SensorType.extrinsic_key must be T_B<X> (the sensor frame X in the body frame, e.g. "
                f"T_BL) or None, got {key!r}"
            )


@dataclass(frozen=True)
class Kind:
    """One kind of a scenario part.

    ``build(params, ctx)`` makes the part: for a world, a :class:`cufund.World`; for every other group, a list
    of :class:`cufund.Component` (one or several, e.g. a cascade of controllers), with ``ctx`` a
    :class:`cufund.core.build_context.BuildContext` (vehicle, world, sensors and their extrinsics, seeds; the
    calls through which a part adds to the run).
    ``params`` is a frozen dataclass (units in its field docs); ``defaults()`` returns the params a kind starts
    from before the scenario's keys are applied (a preset), default ``params()``.
    """

    group: str
    name: str
    params: type
    build: Callable[[Any, BuildContext], Any]
    defaults: Callable[[], Any] | None = None
    doc: str = ""
    sensor_type: str | None = None
    """For sensors (required): the name of a registered :class:`SensorType` (imu, magnetometer, barometer, gps,
    lidar, camera, pose or a plug-in's), which gives its topic's message and its mounting key."""

    def __post_init__(self) -> None:
        if self.group not in GROUPS:
            raise ValueError(f"Kind.group must be one of {', '.join(GROUPS)}, got {self.group!r}")
        if not isinstance(self.name, str) or not self.name or self.name != self.name.strip():
            raise ValueError(f"Kind.name must be a non-empty name, got {self.name!r}")
        if not dataclasses.is_dataclass(self.params):
            raise ValueError(f"Kind.params must be a dataclass type, got {self.params!r}")
        if not callable(self.build):
            raise ValueError("Kind.build must be callable: build(params, ctx)")
        if (self.group == "sensor") != (self.sensor_type is not None):
            raise ValueError(
                f"Kind.sensor_type must name a registered SensorType for a sensor kind and be None "
                f"otherwise, got {self.sensor_type!r} for a {self.group} kind"
            )

    def parse(self, values: dict[str, Any], where: str) -> Any:
        """The kind's params from the scenario's keys (unknown keys name the field and list the known ones)."""
        base = self.defaults() if self.defaults is not None else None
        names = [f.name for f in dataclasses.fields(self.params) if f.init]
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ConfigError(
                f"unknown key {unknown[0]!r} in {where} (kind {self.name}); expected one of: "
                f"{', '.join(names) or 'no keys'}"
            )
        try:
            if base is None:
                return self.params(**values)
            return dataclasses.replace(base, **values)
        except ConfigError as e:
            raise ConfigError(_located(str(e), where)) from None
        except (TypeError, ValueError) as e:
            raise ConfigError(f"{where}: {e}") from None


def _located(message: str, where: str) -> str:
    return message if message.startswith(where) else f"{where}: {message}"


_KINDS: dict[str, dict[str, Kind]] = {g: {} for g in GROUPS}
_SENSOR_TYPES: dict[str, SensorType] = {}
_loaded = False


@overload
def register(item: Kind, replace: bool = False) -> Kind: ...


@overload
def register(item: SensorType, replace: bool = False) -> SensorType: ...


def register(item: Kind | SensorType, replace: bool = False) -> Kind | SensorType:
    """Adds a :class:`Kind` or a :class:`SensorType` to the registry (``replace``: overwrite one of the same group
    and name). A sensor kind's type must be registered first. Returns ``item``. cufund's own kinds and the
    installed plug-ins are loaded first, so a kind registered from Python may replace a built-in one (``replace``)
    and may name a built-in sensor type."""
    load_plugins()
    if isinstance(item, SensorType):
        old = _SENSOR_TYPES.get(item.name)
        if old is not None and old != item and not replace:
            raise ValueError(f"a sensor type named {item.name!r} is registered already (pass replace=True)")
        _SENSOR_TYPES[item.name] = item
        return item
    if not isinstance(item, Kind):
        raise TypeError(f"register takes a cufund.core.registry.Kind or SensorType, got {type(item).__name__}")
    kind = item
    if kind.sensor_type is not None and kind.sensor_type not in _SENSOR_TYPES:
        raise ValueError(
            f"sensor kind {kind.name!r}: its sensor_type {kind.sensor_type!r} is not a registered "
            f"SensorType (known: {', '.join(sorted(_SENSOR_TYPES)) or 'none'}); register it first"
        )
    table = _KINDS[kind.group]
    if kind.name in table and not replace and table[kind.name] is not kind:
        raise ValueError(f"a {kind.group} kind named {kind.name!r} is registered already (pass replace=True)")
    table[kind.name] = kind
    return kind


def unregister(group: str, name: str) -> None:
    """Removes the kind ``name`` of ``group`` (``group="sensor_type"``: the sensor type ``name``)."""
    load_plugins()
    if group == "sensor_type":
        users = sorted(k.name for k in _KINDS["sensor"].values() if k.sensor_type == name)
        if users:
            raise ValueError(
                f"sensor type {name!r} is used by the sensor kinds {', '.join(users)}; unregister them first"
            )
        _SENSOR_TYPES.pop(name, None)
    else:
        _KINDS[group].pop(name, None)


def load_plugins() -> None:
    """Loads every entry point of the group ``cufund.kinds`` once: cufund's own kinds first (they register
    through the same entry points as plug-ins, so this module names no package above it), then the others, which
    may replace a built-in kind. An entry point may name a :class:`Kind` or :class:`SensorType`, an iterable of
    them (sensor types before the kinds that name them), a function returning either, or a module whose import
    registers its kinds."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    from importlib.metadata import entry_points

    eps = sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: (not ep.value.startswith("cufund."), ep.name))
    if not any(ep.value.startswith("cufund.") for ep in eps):
        raise RuntimeError(
            "cufund's built-in kinds are not registered: its entry points (group cufund.kinds) are "
            "missing; reinstall cufund (pip install .)"
        )
    for ep in eps:
        try:
            obj = ep.load()
            if isinstance(obj, types.ModuleType):
                continue  # importing the module registered its kinds
            if callable(obj) and not isinstance(obj, (Kind, SensorType)):
                obj = obj()
            for k in [obj] if isinstance(obj, (Kind, SensorType)) else list(obj):
                register(k, replace=True)
        except Exception as e:  # a broken plug-in must not take cufund down; it is named when used
            if ep.value.startswith("cufund."):
                raise
            _BROKEN[ep.name] = f"{type(e).__name__}: {e}"


_BROKEN: dict[str, str] = {}


def lookup(group: str, name: Any, where: str | None = None) -> Kind:
    """The kind ``name`` of ``group``; a ConfigError naming ``where`` and the known kinds otherwise."""
    load_plugins()
    if group not in _KINDS:
        raise ValueError(f"group must be one of {', '.join(GROUPS)}, got {group!r}")
    where = where or group
    table = _KINDS[group]
    if not isinstance(name, str) or name not in table:
        broken = "".join(f"; plug-in {k!r} failed to load ({v})" for k, v in _BROKEN.items())
        raise ConfigError(f"{where}.kind must be one of {', '.join(sorted(table))}, got {name!r}{broken}")
    return table[name]


def available(group: str) -> dict[str, Kind]:
    """The registered kinds of ``group`` by name."""
    load_plugins()
    return dict(_KINDS[group])


def sensor_type(name: str) -> SensorType:
    """The registered sensor type ``name`` (a KeyError naming the known ones otherwise)."""
    load_plugins()
    found = _SENSOR_TYPES.get(name)
    if found is None:
        raise KeyError(f"no sensor type named {name!r}; known: {', '.join(sorted(_SENSOR_TYPES)) or 'none'}")
    return found


def sensor_types() -> dict[str, SensorType]:
    """The registered sensor types by name."""
    load_plugins()
    return dict(_SENSOR_TYPES)


def extrinsic_keys() -> frozenset[str]:
    """Every mounting key a registered sensor type declares (``T_BI``, ``T_BL``, ``T_BC``, ...)."""
    load_plugins()
    return frozenset(t.extrinsic_key for t in _SENSOR_TYPES.values() if t.extrinsic_key is not None)

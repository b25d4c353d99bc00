"""The registry of scenario kinds: each part of a scenario (world, sensors, estimator, mapper, planner,
controller, mission) names a ``kind`` that maps to a factory and a typed, frozen params dataclass.

Users add kinds from Python with :func:`register`, or from an installed package through the entry-point group
``cufund.kinds``: each entry point names a :class:`Kind`, an iterable of them, or a function returning either::

    [project.entry-points."cufund.kinds"]
    my_ekf = "my_package.cufund_kinds:KINDS"
"""

from __future__ import annotations

import dataclasses
import types
from dataclasses import dataclass
from typing import Any, Callable

from .errors import ConfigError

__all__ = ["ENTRY_POINT_GROUP", "GROUPS", "Kind", "available", "load_plugins", "lookup", "register", "unregister"]

ENTRY_POINT_GROUP = "cufund.kinds"
GROUPS = ("world", "sensor", "estimator", "mapper", "planner", "controller", "mission")
"""The parts of a scenario that take a ``kind``."""



@dataclass(frozen=True)
class Kind:
    """One kind of a scenario part.

    ``build(params, ctx)`` makes the part: for a world, a :class:`cufund.World`; for every other group, a list
    of :class:`cufund.Component` (one or several, e.g. a cascade of controllers), with ``ctx`` a
    :class:`cufund.scenarios.build.BuildContext` (vehicle, world, sensors and their extrinsics, seeds).
    ``params`` is a frozen dataclass (units in its field docs); ``defaults()`` returns the params a kind starts
    from before the scenario's keys are applied (a preset), default ``params()``.
    """

    group: str
    name: str
    params: type
    build: Callable[[Any, Any], Any]
    defaults: Callable[[], Any] | None = None
    doc: str = ""
    sensor_type: str | None = None
    """For sensors: imu, magnetometer, barometer, gps, lidar, camera or pose (what the scenario may look up)."""

    def __post_init__(self) -> None:
        if self.group not in GROUPS:
            raise ValueError(f"Kind.group must be one of {', '.join(GROUPS)}, got {self.group!r}")
        if not isinstance(self.name, str) or not self.name or self.name != self.name.strip():
            raise ValueError(f"Kind.name must be a non-empty name, got {self.name!r}")
        if not dataclasses.is_dataclass(self.params):
            raise ValueError(f"Kind.params must be a dataclass type, got {self.params!r}")
        if not callable(self.build):
            raise ValueError("Kind.build must be callable: build(params, ctx)")

    def parse(self, values: dict[str, Any], where: str) -> Any:
        """The kind's params from the scenario's keys (unknown keys name the field and list the known ones)."""
        base = self.defaults() if self.defaults is not None else None
        names = [f.name for f in dataclasses.fields(self.params) if f.init]
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ConfigError(f"unknown key {unknown[0]!r} in {where} (kind {self.name}); expected one of: "
                              f"{', '.join(names) or 'no keys'}")
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
_loaded = False


def register(kind: Kind, replace: bool = False) -> Kind:
    """Adds ``kind`` to the registry (``replace``: overwrite one of the same group and name). Returns it."""
    if not isinstance(kind, Kind):
        raise TypeError(f"register takes a cufund.core.registry.Kind, got {type(kind).__name__}")
    table = _KINDS[kind.group]
    if kind.name in table and not replace and table[kind.name] is not kind:
        raise ValueError(f"a {kind.group} kind named {kind.name!r} is registered already (pass replace=True)")
    table[kind.name] = kind
    return kind


def unregister(group: str, name: str) -> None:
    _KINDS[group].pop(name, None)


def load_plugins() -> None:
    """Loads every entry point of the group ``cufund.kinds`` once: cufund's own kinds first (they register
    through the same entry points as plug-ins, so this module names no package above it), then the others, which
    may replace a built-in kind. An entry point may name a :class:`Kind`, an iterable of kinds, a function
    returning either, or a module whose import registers its kinds."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    from importlib.metadata import entry_points

    eps = sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: (not ep.value.startswith("cufund."), ep.name))
    if not any(ep.value.startswith("cufund.") for ep in eps):
        raise RuntimeError("cufund's built-in kinds are not registered: its entry points (group cufund.kinds) are "
                           "missing; reinstall cufund (pip install .)")
    for ep in eps:
        try:
            obj = ep.load()
            if isinstance(obj, types.ModuleType):
                continue  # importing the module registered its kinds
            if callable(obj) and not isinstance(obj, Kind):
                obj = obj()
            for k in ([obj] if isinstance(obj, Kind) else list(obj)):
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

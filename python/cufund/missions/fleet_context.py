"""What a fleet mission is planned and checked against: the vehicles' names and homes, named fields, the geofence and
the altitude and size limits (:class:`FleetContext`). :meth:`FleetContext.of` reads it from a built fleet
(:func:`cufund.scenarios.fleet.build_fleet`), a mapping (YAML or JSON) or nothing (one vehicle ``uav1`` at the
origin, no geofence)."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from .fleet_polygon import Polygon, check_polygon

__all__ = ["NAME_PATTERN", "FleetContext", "MissionRequestError"]

NAME_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,31}$")
"""A vehicle's or a field's name."""


class MissionRequestError(ValueError):
    """A mission request that cannot be flown, with the reason in words (malformed, unsafe, unknown vehicle, ...)."""


def _positive(name: str, v: Any) -> float:
    try:
        f = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan
    except OverflowError:
        f = math.nan
    if not math.isfinite(f) or f <= 0:
        raise MissionRequestError(f"fleet context: {name} must be a finite number > 0, got {str(v)[:40]}")
    return f


@dataclass(frozen=True)
class FleetContext:
    """The fleet a mission request is planned for and the limits it must respect (positions ENU [m], ground at
    z = 0)."""

    names: tuple[str, ...] = ("uav1",)
    """The vehicles, in order (the first has the highest priority when trajectories are deconflicted)."""
    homes: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    """Each vehicle's home (its start; missing: the origin)."""
    fields: Mapping[str, Polygon] = field(default_factory=dict)
    """Named areas a request may refer to ("survey the field")."""
    geofence: Polygon | None = None
    """Every waypoint must lie inside this polygon (None: no horizontal fence)."""
    min_altitude: float = 1.0
    """Lowest waypoint height [m]."""
    max_altitude: float = 50.0
    """Highest waypoint height [m]."""
    max_waypoints: int = 500
    """Most waypoints one vehicle may be given."""
    default_altitude: float = 5.0
    """Height of a request that names none [m]."""
    default_spacing: float = 2.0
    """Lane spacing of a survey and point spacing of a zigzag without an area, when the request names none [m]."""
    return_altitude: float = 2.0
    """Height above home of a return's last waypoint [m] (the commander's ``rtl`` picks its own)."""
    commander: Any = None
    """The vehicles' :class:`~cufund.missions.params.CommanderParams` (how they fly; None: the defaults), for the
    missions timed across the fleet (a formation's synchronised start)."""

    def __post_init__(self) -> None:
        names = tuple(self.names)
        if not names or len(names) > 1000:
            raise MissionRequestError(f"fleet context: names must list 1 to 1000 vehicles, got {len(names)}")
        for n in names:
            if not isinstance(n, str) or not NAME_PATTERN.match(n):
                raise MissionRequestError(f"fleet context: vehicle name {n!r} must match {NAME_PATTERN.pattern}")
        if len(set(names)) != len(names):
            raise MissionRequestError(f"fleet context: vehicle names repeat: {list(names)}")
        object.__setattr__(self, "names", names)
        homes = {}
        for n, p in dict(self.homes).items():
            if n not in names:
                raise MissionRequestError(f"fleet context: home of unknown vehicle {n!r}")
            v = np.asarray(p, dtype=float).reshape(-1)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise MissionRequestError(f"fleet context: homes.{n} must be [x, y, z] [m], got {p!r}")
            homes[n] = (float(v[0]), float(v[1]), float(v[2]))
        object.__setattr__(self, "homes", homes)
        fld = {}
        for n, poly in dict(self.fields).items():
            if not isinstance(n, str) or not NAME_PATTERN.match(n):
                raise MissionRequestError(f"fleet context: field name {n!r} must match {NAME_PATTERN.pattern}")
            try:
                fld[n] = check_polygon(poly, f"fields.{n}")
            except ValueError as e:
                raise MissionRequestError(f"fleet context: {e}") from None
        object.__setattr__(self, "fields", fld)
        if self.geofence is not None:
            try:
                object.__setattr__(self, "geofence", check_polygon(self.geofence, "geofence"))
            except ValueError as e:
                raise MissionRequestError(f"fleet context: {e}") from None
        for f in ("min_altitude", "max_altitude", "default_altitude", "default_spacing", "return_altitude"):
            object.__setattr__(self, f, _positive(f, getattr(self, f)))
        if self.max_altitude < self.min_altitude:
            raise MissionRequestError("fleet context: max_altitude must be at least min_altitude")
        from .params import CommanderParams

        if self.commander is not None and not isinstance(self.commander, CommanderParams):
            raise MissionRequestError(
                f"fleet context: commander must be CommanderParams or None, got {self.commander!r}"
            )
        m = self.max_waypoints
        if isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= 10000:
            raise MissionRequestError(f"fleet context: max_waypoints must be an integer in [1, 10000], got {m!r}")

    def home(self, name: str) -> np.ndarray:
        """Vehicle ``name``'s home (3,) [m]."""
        return np.asarray(self.homes.get(name, (0.0, 0.0, 0.0)), dtype=float)

    @classmethod
    def from_data(cls, data: Mapping[str, Any]) -> FleetContext:
        """From a mapping of the field names (unknown keys refused)."""
        if not isinstance(data, Mapping):
            raise MissionRequestError(f"fleet context must be a mapping, got {type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise MissionRequestError(f"fleet context: unknown key(s) {unknown}; known: {sorted(known)}")
        kw = dict(data)
        if "names" in kw:
            kw["names"] = tuple(kw["names"])
        return cls(**kw)

    @classmethod
    def of(cls, fleet: Any = None) -> FleetContext:
        """The context of ``fleet``: a :class:`FleetContext` as is; None the default; a mapping through
        :meth:`from_data`; a built fleet (``names`` and ``vehicle(name)``) with each vehicle's home (its
        commander's home once armed, else its start), the fields, geofence and limits of its scenario's ``fleet``
        mission if it has one, and those of its ``mission_context`` (a mapping) if it offers one."""
        if fleet is None:
            return cls()
        if isinstance(fleet, FleetContext):
            return fleet
        if isinstance(fleet, Mapping):
            return cls.from_data(fleet)
        names = getattr(fleet, "names", None)
        if names is None or not hasattr(fleet, "vehicle"):
            raise MissionRequestError(
                f"fleet must be a FleetContext, a mapping or a built fleet (names, vehicle(name)), got "
                f"{type(fleet).__name__}"
            )
        from .params import CommanderParams

        homes = {}
        commander = None
        for n in names:
            v = fleet.vehicle(n)
            params = getattr(getattr(v, "commander", None), "params", None)
            if commander is None and isinstance(params, CommanderParams):
                commander = params
            home = getattr(getattr(v, "commander", None), "home_p_W", None)
            if home is None or not np.all(np.isfinite(home)):
                cfg = getattr(v, "config", None)
                home = getattr(cfg, "start_p_W", None) if cfg is not None else None
            homes[n] = tuple(home) if home is not None else (0.0, 0.0, 0.0)
        extra: dict[str, Any] = {}
        mission = getattr(getattr(fleet, "config", None), "mission", None)
        if getattr(mission, "kind", None) == "fleet":  # the scenario's fleet mission: its fields, fence and limits
            p = mission.params  # type: ignore[union-attr]
            extra = {
                "fields": dict(p.fields),
                "geofence": p.geofence,
                "min_altitude": p.min_altitude,
                "max_altitude": p.max_altitude,
                "max_waypoints": p.max_waypoints,
            }
        extra.update(getattr(fleet, "mission_context", None) or {})
        extra.pop("names", None)
        extra.pop("homes", None)
        extra.setdefault("commander", commander)
        return cls.from_data({"names": tuple(names), "homes": homes, **extra})

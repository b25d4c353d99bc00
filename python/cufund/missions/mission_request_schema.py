"""The typed fleet missions a request becomes, and their one validation for every source (the offline grammar, a
chat endpoint's JSON, a ground station's form): :func:`mission_from_data` reads the plain data, each mission's
constructor checks its own fields, and :meth:`Mission.check` checks it against a :class:`FleetContext` (known
vehicles, waypoints inside the geofence, above the minimum altitude, not too many). Anything refused raises
:class:`MissionRequestError` with the reason.

The data form (JSON), one object with ``"mission"`` one of :data:`MISSIONS`:

- ``{"mission": "zigzag", "rows": 3, "per_row": 5, "altitude": 10, "area": "field" | [[x, y], ...] | null,
  "spacing": 2, "vehicles": "all" | ["uav1", ...]}``
- ``{"mission": "orbit", "center": [x, y], "radius": 3, "altitude": 5, "laps": 1, "vehicles": ...}``
- ``{"mission": "survey", "area": "field" | [[x, y], ...], "spacing": 2, "altitude": 5, "vehicles": ...}``
- ``{"mission": "go_home", "vehicles": ...}``
- ``{"mission": "waypoints", "points": [[x, y, z], ...], "vehicles": ["uav1"]}``
- ``{"mission": "formation", "path": [[x, y, z], ...], "shape": "wedge" | "line" | "column", "spacing": 3,
  "vehicles": ...}``

Positions ENU [m] (ground at z = 0), altitudes are heights above ground [m]; omitted fields take the context's
defaults; ``"area": "selection"`` is the area the caller selected (``area=`` of :func:`mission_from_data`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .commands import Command, parse_command
from .coverage import crossings, fewest_lanes, plan_coverage, sweep_frame
from .fleet_context import NAME_PATTERN, FleetContext, MissionRequestError
from .fleet_polygon import MAX_VERTICES, Polygon, check_polygon, polygon_contains
from .fleet_timing import item_arrivals
from .formation import SHAPES, formation_offsets

__all__ = [
    "MISSIONS",
    "Formation",
    "GoHome",
    "Mission",
    "Orbit",
    "Survey",
    "Waypoints",
    "Zigzag",
    "mission_from_data",
]

MISSIONS = ("zigzag", "orbit", "survey", "go_home", "waypoints", "formation")
ORBIT_POINTS_PER_LAP = 12
"""Waypoints per orbit lap (every 30 degrees)."""
_MAX_COUNT = 10000


def _finite(v: Any) -> float | None:
    """``v`` as a finite float, or None (not a number, a bool, NaN, infinite, an integer too large for a float)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        f = float(v)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def _num(where: str, v: Any, lo: float | None = None, positive: bool = False) -> float:
    f = _finite(v)
    if f is None or abs(f) > 1e6:
        raise MissionRequestError(f"{where} must be a finite number (within 1000 km), got {str(v)[:40]}")
    v = f
    if positive and v <= 0:
        raise MissionRequestError(f"{where} must be > 0, got {v!r}")
    if lo is not None and v < lo:
        raise MissionRequestError(f"{where} must be at least {lo:g}, got {v!r}")
    return float(v)


def _int(where: str, v: Any, lo: int, hi: int) -> int:
    f = _finite(v)
    if f is None or not f.is_integer():
        raise MissionRequestError(f"{where} must be a whole number, got {str(v)[:40]}")
    if not lo <= v <= hi:
        raise MissionRequestError(f"{where} must be between {lo} and {hi}, got {v!r}")
    return int(v)


def _vec(where: str, v: Any, n: int) -> tuple[float, ...]:
    if isinstance(v, (str, bytes, Mapping)) or not isinstance(v, Sequence) or len(v) != n:
        raise MissionRequestError(f"{where} must be a list of {n} numbers [m], got {v!r}"[:300])
    return tuple(_num(f"{where}[{i}]", c) for i, c in enumerate(v))


def _vehicles(v: Any) -> tuple[str, ...]:
    """``()`` means every vehicle of the fleet."""
    if v is None or v == "all":
        return ()
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, Sequence) or len(v) > 1000:
        raise MissionRequestError(f"vehicles must be 'all' or a list of up to 1000 vehicle names, got {v!r}"[:300])
    out = []
    for n in v:
        if not isinstance(n, str) or not NAME_PATTERN.match(n):
            raise MissionRequestError(f"vehicle name {n!r} is not a name (letters, digits, _ or -)"[:300])
        out.append(n)
    if len(set(out)) != len(out):
        raise MissionRequestError(f"vehicles repeat: {out}")
    return tuple(out)


def _polygon(where: str, v: Any) -> Polygon:
    if isinstance(v, Sequence) and not isinstance(v, str) and len(v) > MAX_VERTICES:
        raise MissionRequestError(f"{where} must have at most {MAX_VERTICES} vertices, got {len(v)}")
    try:
        return check_polygon(v, where)
    except ValueError as e:
        raise MissionRequestError(str(e)[:300]) from None


class Mission:
    """A validated fleet mission (frozen); :meth:`waypoints` gives each vehicle's waypoints."""

    kind: ClassVar[str]
    vehicles: tuple[str, ...]

    def flying(self, ctx: FleetContext) -> tuple[str, ...]:
        """The vehicles that fly it (``vehicles``, or every vehicle of the fleet)."""
        return self.vehicles or ctx.names

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:  # pragma: no cover - abstract
        raise NotImplementedError

    def waypoints(self, fleet: Any = None) -> dict[str, np.ndarray]:
        """``{vehicle: (N, 3) ENU waypoints [m]}`` for ``fleet`` (see :meth:`FleetContext.of`), checked."""
        ctx = FleetContext.of(fleet)
        self.check(ctx)
        return self.plan(ctx)

    def check(self, ctx: FleetContext) -> None:
        """Refuses (:class:`MissionRequestError` with the reason) a mission that ``ctx`` cannot fly: an unknown
        vehicle, too many waypoints, a waypoint outside the geofence, below ground or the minimum altitude, or above
        the maximum."""
        unknown = [n for n in self.vehicles if n not in ctx.names]
        if unknown:
            raise MissionRequestError(f"unknown vehicle {', '.join(unknown)}: the fleet has {', '.join(ctx.names)}")
        self.precheck(ctx)
        for name, wp in self.plan(ctx).items():
            if len(wp) > ctx.max_waypoints:
                raise MissionRequestError(
                    f"too many waypoints: {len(wp)} for {name}, at most {ctx.max_waypoints} per vehicle"
                )
            z = wp[:, 2]
            if np.any(z <= 0):
                raise MissionRequestError(f"below ground: {name}'s waypoints reach z = {z.min():g} m")
            if np.any(z < ctx.min_altitude - 1e-9):
                raise MissionRequestError(
                    f"below the minimum altitude: {name}'s waypoints reach {z.min():g} m, the minimum is "
                    f"{ctx.min_altitude:g} m"
                )
            if np.any(z > ctx.max_altitude + 1e-9):
                raise MissionRequestError(
                    f"above the maximum altitude: {name}'s waypoints reach {z.max():g} m, the maximum is "
                    f"{ctx.max_altitude:g} m"
                )
            if ctx.geofence is not None:
                inside = polygon_contains(ctx.geofence, wp[:, :2], tol=1e-6)
                if not inside.all():
                    x, y = wp[int(np.argmin(inside)), :2]
                    raise MissionRequestError(f"outside the geofence: {name}'s waypoint ({x:g}, {y:g}) m")

    def precheck(self, ctx: FleetContext) -> None:
        """Checks before planning (sizes that would make planning itself too large)."""

    def to_data(self) -> dict[str, Any]:
        """The plain data :func:`mission_from_data` reads back."""
        raise NotImplementedError

    def holds(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        """How long each vehicle waits at each of its waypoints [s] (none but for a formation's assembly)."""
        return {n: np.zeros(len(wp)) for n, wp in self.plan(ctx).items()}

    def commands(self, fleet: Any = None) -> dict[str, list[Command]]:
        """The commander commands that fly it, per vehicle: ``mission_upload`` of the waypoints (with their
        :meth:`holds`) and ``mission_start`` (a return: ``rtl``)."""
        ctx = FleetContext.of(fleet)
        wps = self.waypoints(ctx)
        holds = self.holds(ctx)
        return {
            n: [
                parse_command(
                    {
                        "command": "mission_upload",
                        "items": [
                            {"p_W": [float(c) for c in p], "hold_s": float(h)}
                            for p, h in zip(wp, holds[n], strict=True)
                        ],
                    }
                ),
                parse_command({"command": "mission_start"}),
            ]
            for n, wp in wps.items()
        }


def _area_data(area: Any) -> Any:
    return area if isinstance(area, str) or area is None else [list(p) for p in area]


def _resolve_area(where: str, area: Any, ctx: FleetContext) -> Polygon:
    if isinstance(area, str):
        if area not in ctx.fields:
            known = ", ".join(ctx.fields) or "none"
            raise MissionRequestError(f"{where}: no field named {area!r} (known fields: {known})")
        return ctx.fields[area]
    return area


@dataclass(frozen=True)
class Zigzag(Mission):
    """``rows`` rows of ``per_row`` waypoints flown back and forth (boustrophedon) at ``altitude`` [m]: over
    ``area`` (a field's name or a polygon: rows across its width along its longest edge, each row's waypoints at
    the centres of per_row equal parts of its length inside the area, so a row across a non-convex area's gap has
    none in it) or, without one, a grid ``spacing`` [m] apart starting at the vehicle's home (rows
    along +x, stacked along +y). Several vehicles share the rows, each a contiguous block."""

    kind: ClassVar[str] = "zigzag"
    rows: int
    per_row: int
    altitude: float
    area: str | Polygon | None = None
    spacing: float | None = None
    vehicles: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "rows", _int("zigzag rows", self.rows, 1, _MAX_COUNT))
        object.__setattr__(self, "per_row", _int("zigzag waypoints per row", self.per_row, 1, _MAX_COUNT))
        object.__setattr__(self, "altitude", _num("zigzag altitude [m]", self.altitude))
        if self.area is not None and not isinstance(self.area, str):
            object.__setattr__(self, "area", _polygon("zigzag area", self.area))
        if self.spacing is not None:
            object.__setattr__(self, "spacing", _num("zigzag spacing [m]", self.spacing, positive=True))
        object.__setattr__(self, "vehicles", _vehicles(self.vehicles))

    def precheck(self, ctx: FleetContext) -> None:
        n = len(self.flying(ctx))
        if self.rows < n:
            raise MissionRequestError(f"a zigzag of {self.rows} row(s) cannot be shared by {n} vehicles")
        if self.rows * self.per_row > ctx.max_waypoints * n:
            raise MissionRequestError(
                f"too many waypoints: {self.rows} x {self.per_row} for {n} vehicle(s), at most "
                f"{ctx.max_waypoints} per vehicle"
            )

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        names = self.flying(ctx)
        if self.area is None:
            s = self.spacing or ctx.default_spacing
            origin = ctx.home(names[0])
            rows = [[(origin[0] + j * s, origin[1] + i * s) for j in range(self.per_row)] for i in range(self.rows)]
        else:
            poly = np.asarray(_resolve_area("zigzag area", self.area, ctx))
            u, w = sweep_frame(poly)  # u along the longest edge, w across
            pw = poly @ w
            lo, hi = float(pw.min()), float(pw.max())
            centres = lo + (np.arange(self.rows) + 0.5) * (hi - lo) / self.rows
            rows = []
            for c, pieces in zip(centres, crossings(poly, u, w, centres), strict=True):
                inside = sum(b - a for a, b in pieces)
                row = []
                for j in range(self.per_row):  # the centres of per_row equal parts of the row's length inside
                    t = (j + 0.5) * inside / self.per_row
                    for k, (a, b) in enumerate(pieces):
                        if t <= b - a or k == len(pieces) - 1:
                            break
                        t -= b - a  # past this piece: on to the next, across the gap
                    row.append(tuple((a + t) * u + c * w))
                rows.append(row)
        out = {}
        for name, block in zip(names, np.array_split(np.arange(self.rows), len(names)), strict=True):
            pts = []
            for i in block:
                pts += rows[i] if i % 2 == 0 else rows[i][::-1]
            out[name] = np.array([(x, y, self.altitude) for x, y in pts], dtype=float)
        return out

    def to_data(self) -> dict[str, Any]:
        return {
            "mission": "zigzag",
            "rows": self.rows,
            "per_row": self.per_row,
            "altitude": self.altitude,
            "area": _area_data(self.area),
            "spacing": self.spacing,
            "vehicles": list(self.vehicles) or "all",
        }


@dataclass(frozen=True)
class Orbit(Mission):
    """``laps`` counter-clockwise laps of radius ``radius`` [m] around ``center`` (x, y) [m] at ``altitude`` [m],
    :data:`ORBIT_POINTS_PER_LAP` waypoints a lap, starting east of the centre; several vehicles fly it spread evenly
    around the circle."""

    kind: ClassVar[str] = "orbit"
    center: tuple[float, float]
    radius: float
    altitude: float
    laps: int = 1
    vehicles: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec("orbit center", self.center, 2))
        object.__setattr__(self, "radius", _num("orbit radius [m]", self.radius, positive=True))
        object.__setattr__(self, "altitude", _num("orbit altitude [m]", self.altitude))
        object.__setattr__(self, "laps", _int("orbit laps", self.laps, 1, 100))
        object.__setattr__(self, "vehicles", _vehicles(self.vehicles))

    def precheck(self, ctx: FleetContext) -> None:
        n = self.laps * ORBIT_POINTS_PER_LAP + 1
        if n > ctx.max_waypoints:
            raise MissionRequestError(
                f"too many waypoints: {self.laps} laps are {n} waypoints, at most {ctx.max_waypoints} per vehicle"
            )

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        names = self.flying(ctx)
        k = np.arange(self.laps * ORBIT_POINTS_PER_LAP + 1)
        out = {}
        for i, name in enumerate(names):
            a = 2 * math.pi * (i / len(names) + k / ORBIT_POINTS_PER_LAP)
            out[name] = np.stack(
                [
                    self.center[0] + self.radius * np.cos(a),
                    self.center[1] + self.radius * np.sin(a),
                    np.full(len(a), self.altitude),
                ],
                axis=1,
            )
        return out

    def to_data(self) -> dict[str, Any]:
        return {
            "mission": "orbit",
            "center": list(self.center),
            "radius": self.radius,
            "altitude": self.altitude,
            "laps": self.laps,
            "vehicles": list(self.vehicles) or "all",
        }


@dataclass(frozen=True)
class Survey(Mission):
    """Coverage of ``area`` (a field's name or a polygon) split between the vehicles, lanes ``spacing`` [m] apart at
    ``altitude`` [m] (:func:`cufund.missions.coverage.plan_coverage`)."""

    kind: ClassVar[str] = "survey"
    area: str | Polygon
    spacing: float
    altitude: float
    vehicles: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.area, str):
            object.__setattr__(self, "area", _polygon("survey area", self.area))
        object.__setattr__(self, "spacing", _num("survey spacing [m]", self.spacing, lo=0.1))
        object.__setattr__(self, "altitude", _num("survey altitude [m]", self.altitude))
        object.__setattr__(self, "vehicles", _vehicles(self.vehicles))

    def precheck(self, ctx: FleetContext) -> None:
        poly = np.asarray(_resolve_area("survey area", self.area, ctx))
        n = len(self.flying(ctx))
        fewest = fewest_lanes(poly, self.spacing)
        if 2 * fewest > ctx.max_waypoints * n:  # two waypoints a lane at least
            raise MissionRequestError(
                f"too many waypoints: the area at {self.spacing:g} m spacing needs at least {2 * fewest} "
                f"waypoints ({fewest} lanes), at most {ctx.max_waypoints} per vehicle for {n} vehicle(s)"
            )
        if ctx.geofence is not None:
            inside = polygon_contains(ctx.geofence, poly, tol=1e-6)
            if not inside.all():
                x, y = poly[int(np.argmin(inside))]
                raise MissionRequestError(f"outside the geofence: the survey area's corner ({x:g}, {y:g}) m")

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        names = self.flying(ctx)
        poly = _resolve_area("survey area", self.area, ctx)
        try:
            cells = plan_coverage(
                poly,
                {n: ctx.home(n) for n in names},
                self.spacing,
                self.altitude,
                max_lanes=ctx.max_waypoints * len(names) // 2,  # a sweep of more could not be flown
            )
        except ValueError as e:
            raise MissionRequestError(f"survey: {e}") from None
        return {n: np.asarray(cells[n].path, dtype=float) for n in names}

    def to_data(self) -> dict[str, Any]:
        return {
            "mission": "survey",
            "area": _area_data(self.area),
            "spacing": self.spacing,
            "altitude": self.altitude,
            "vehicles": list(self.vehicles) or "all",
        }


@dataclass(frozen=True)
class GoHome(Mission):
    """Return home (the commander's ``rtl``); as waypoints: the point ``return_altitude`` above each home."""

    kind: ClassVar[str] = "go_home"
    vehicles: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "vehicles", _vehicles(self.vehicles))

    def check(self, ctx: FleetContext) -> None:  # going home is never refused for its waypoints
        unknown = [n for n in self.vehicles if n not in ctx.names]
        if unknown:
            raise MissionRequestError(f"unknown vehicle {', '.join(unknown)}: the fleet has {', '.join(ctx.names)}")

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        return {n: (ctx.home(n) + [0.0, 0.0, ctx.return_altitude])[None, :] for n in self.flying(ctx)}

    def commands(self, fleet: Any = None) -> dict[str, list[Command]]:
        ctx = FleetContext.of(fleet)
        self.check(ctx)
        return {n: [parse_command({"command": "rtl"})] for n in self.flying(ctx)}

    def to_data(self) -> dict[str, Any]:
        return {"mission": "go_home", "vehicles": list(self.vehicles) or "all"}


@dataclass(frozen=True)
class Waypoints(Mission):
    """``points`` ((x, y, z) [m]) for one vehicle."""

    kind: ClassVar[str] = "waypoints"
    points: tuple[tuple[float, float, float], ...]
    vehicles: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        p = self.points
        if isinstance(p, (str, bytes, Mapping)) or not isinstance(p, Sequence) or not p:
            raise MissionRequestError(f"waypoints points must be a non-empty list of [x, y, z] [m], got {p!r}"[:300])
        if len(p) > _MAX_COUNT:
            raise MissionRequestError(f"too many waypoints: {len(p)}, at most {_MAX_COUNT}")
        object.__setattr__(self, "points", tuple(_vec(f"points[{i}]", v, 3) for i, v in enumerate(p)))
        object.__setattr__(self, "vehicles", _vehicles(self.vehicles))

    def precheck(self, ctx: FleetContext) -> None:
        if len(self.flying(ctx)) != 1:
            raise MissionRequestError(
                f"a list of waypoints is for one vehicle: name it (e.g. 'with {ctx.names[0]}') or select one; "
                f"the fleet has {', '.join(ctx.names)}"
            )
        if len(self.points) > ctx.max_waypoints:
            raise MissionRequestError(
                f"too many waypoints: {len(self.points)}, at most {ctx.max_waypoints} per vehicle"
            )

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        return {self.flying(ctx)[0]: np.asarray(self.points, dtype=float)}

    def to_data(self) -> dict[str, Any]:
        return {"mission": "waypoints", "points": [list(p) for p in self.points], "vehicles": list(self.vehicles)}


@dataclass(frozen=True)
class Formation(Mission):
    """The vehicles fly ``path`` ((x, y, z) [m]) together as a rigid ``shape`` (:data:`~cufund.missions.formation.
    SHAPES`) with neighbours ``spacing`` [m] apart: a virtual structure (:mod:`cufund.missions.formation`) whose
    reference point flies the path, oriented along the path's first leg and kept so (a translation: every vehicle's
    leg is the same move, so the commanders fly them in step). Vehicle k (in the fleet's order) takes slot k; they
    assemble at the path's start, the earlier ones waiting there (:meth:`holds`) until the last has arrived."""

    kind: ClassVar[str] = "formation"
    path: tuple[tuple[float, float, float], ...]
    shape: str = "wedge"
    spacing: float = 3.0
    vehicles: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        p = self.path
        if isinstance(p, (str, bytes, Mapping)) or not isinstance(p, Sequence) or len(p) < 2:
            raise MissionRequestError(f"formation path must list at least two [x, y, z] [m], got {p!r}"[:300])
        if len(p) > _MAX_COUNT:
            raise MissionRequestError(f"too many waypoints: {len(p)}, at most {_MAX_COUNT}")
        object.__setattr__(self, "path", tuple(_vec(f"path[{i}]", v, 3) for i, v in enumerate(p)))
        if self.shape not in SHAPES:
            raise MissionRequestError(f"formation shape must be one of {', '.join(SHAPES)}, got {self.shape!r}"[:300])
        object.__setattr__(self, "spacing", _num("formation spacing [m]", self.spacing, lo=0.5))
        object.__setattr__(self, "vehicles", _vehicles(self.vehicles))
        d = np.asarray(self.path[1][:2]) - np.asarray(self.path[0][:2])
        if float(np.hypot(*d)) < 1e-6:
            raise MissionRequestError("formation path: its first leg must move horizontally (it sets the heading)")

    def precheck(self, ctx: FleetContext) -> None:
        if len(self.path) > ctx.max_waypoints:
            raise MissionRequestError(f"too many waypoints: {len(self.path)}, at most {ctx.max_waypoints} per vehicle")

    def plan(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        names = self.flying(ctx)
        offsets = formation_offsets(self.shape, len(names), self.spacing)
        d = np.asarray(self.path[1]) - np.asarray(self.path[0])
        h = math.atan2(d[1], d[0])
        R = np.array([[math.cos(h), -math.sin(h), 0.0], [math.sin(h), math.cos(h), 0.0], [0.0, 0.0, 1.0]])
        path = np.asarray(self.path, dtype=float)
        return {n: path + R @ o for n, o in zip(names, offsets, strict=True)}

    def holds(self, ctx: FleetContext) -> dict[str, np.ndarray]:
        wps = self.plan(ctx)
        arrive = {n: float(item_arrivals(ctx.home(n), wp[:1], ctx.commander)[0]) for n, wp in wps.items()}
        last = max(arrive.values())
        out = {}
        for n, wp in wps.items():
            h = np.zeros(len(wp))
            h[0] = last - arrive[n]
            out[n] = h
        return out

    def to_data(self) -> dict[str, Any]:
        return {
            "mission": "formation",
            "path": [list(p) for p in self.path],
            "shape": self.shape,
            "spacing": self.spacing,
            "vehicles": list(self.vehicles) or "all",
        }


_FIELDS: dict[str, tuple[type[Mission], tuple[str, ...], tuple[str, ...]]] = {
    # kind: (class, required keys, optional keys)
    "zigzag": (Zigzag, ("rows", "per_row"), ("altitude", "area", "spacing", "vehicles")),
    "orbit": (Orbit, ("center", "radius"), ("altitude", "laps", "vehicles")),
    "survey": (Survey, (), ("area", "spacing", "altitude", "vehicles")),
    "go_home": (GoHome, (), ("vehicles",)),
    "waypoints": (Waypoints, ("points",), ("vehicles",)),
    "formation": (Formation, ("path",), ("shape", "spacing", "vehicles")),
}


def mission_from_data(data: Any, fleet: Any = None, area: Any = None, vehicles: Sequence[str] | None = None) -> Mission:
    """The mission of ``data`` (the form in the module doc), checked against ``fleet``; ``area`` is the caller's
    selected polygon (for ``"area": "selection"``, and a survey that names no area), ``vehicles`` the selected
    vehicles (for data that names none). Refused: :class:`MissionRequestError` with the reason."""
    ctx = FleetContext.of(fleet)
    if not isinstance(data, Mapping):
        raise MissionRequestError(f"a mission must be a JSON object, got {type(data).__name__}")
    kind = data.get("mission")
    if not isinstance(kind, str) or kind not in _FIELDS:  # a list or an object is no kind (nor hashable)
        raise MissionRequestError(f"mission must be one of {', '.join(MISSIONS)}, got {kind!r}"[:300])
    cls, required, optional = _FIELDS[kind]
    unknown = [k for k in data if k != "mission" and k not in required + optional]
    if unknown:
        raise MissionRequestError(f"{kind}: unknown field(s) {unknown}; allowed: {list(required + optional)}"[:300])
    missing = [k for k in required if data.get(k) is None]
    if missing:
        raise MissionRequestError(f"{kind}: missing {', '.join(missing)}")
    kw = {k: data[k] for k in required + optional if data.get(k) is not None}
    if "vehicles" not in kw and vehicles:
        kw["vehicles"] = list(vehicles)
    if "altitude" in optional:
        kw.setdefault("altitude", ctx.default_altitude)
    if kind == "survey":
        kw.setdefault("spacing", ctx.default_spacing)
        kw.setdefault("area", "selection")
    if kw.get("area") == "selection":
        if area is None:
            known = ", ".join(ctx.fields) or "none"
            raise MissionRequestError(
                f"{kind}: no area selected: select a polygon on the map or name a field (known fields: {known})"
            )
        kw["area"] = area
    mission = cls(**kw)
    mission.check(ctx)
    return mission

"""The offline grammar of mission requests: a sentence in plain English to the data form of
:mod:`cufund.missions.mission_request_schema` (deterministic: regular expressions over the normalised text, no
network). Number words ("three", "twenty-five") read as digits.

What it knows (case and word order are free within reason; "m", "meters" and "metres" are the same):

- zigzag: "Generate a zigzag path with three rows, each row containing five waypoints", "zigzag over the field with
  3 rows of 5 waypoints at 10 m", "lawnmower 4 by 6 at 8 m" (zig-zag, lawnmower, boustrophedon, serpentine)
- orbit: "orbit (4, 2) at radius 3 m", "circle around (0, 0) with a 5 m radius twice at 6 m" (orbit, circle,
  loiter)
- survey: "survey this polygon with all drones", "cover the field at 4 m with 3 m spacing" (survey, cover, scan,
  map)
- go home: "go back home", "return to launch", "RTL", "come home"
- waypoints: "fly to (1, 2, 3) then (4, 5, 3)" (fly to, go to, visit, waypoints)
- formation: "fly in a wedge formation through (0, 0) and (20, 0) at 3 m, 3 m apart" (wedge or V, line abreast,
  column)

Vehicles: "all drones" / "the whole fleet" / "every vehicle" (all), or names ("uav2", "drone 2" = the fleet's
vehicle numbered 2); areas: "this polygon" / "this area" / "the selection" (the caller's selection) or a field's
name ("the field"). A sentence that is none of these raises :class:`GrammarMiss`; a recognised request missing a
part raises :class:`MissionRequestError` naming it.
"""

from __future__ import annotations

import re
from typing import Any

from .fleet_context import FleetContext, MissionRequestError

__all__ = ["GrammarMiss", "normalise", "request_to_data"]


class GrammarMiss(MissionRequestError):
    """The sentence is none of the built-in phrases."""


_UNITS = "zero one two three four five six seven eight nine ten eleven twelve thirteen fourteen fifteen sixteen".split()
_UNITS += "seventeen eighteen nineteen".split()
_TENS = {"twenty": 20, "thirty": 30, "forty": 40, "fifty": 50, "sixty": 60, "seventy": 70, "eighty": 80, "ninety": 90}
_NUMBER_WORDS = re.compile(
    r"\b(?:(?P<tens>" + "|".join(_TENS) + r")(?:[\s-]+(?P<unit>" + "|".join(_UNITS[1:10]) + r"))?"
    r"|(?P<small>" + "|".join(_UNITS) + r"))\b"
)
NUM = r"[-+]?\d+(?:\.\d+)?"
_M = r"\s*(?:m|meters?|metres?)\b"


def _words_to_digits(m: re.Match[str]) -> str:
    if m.group("small"):
        return str(_UNITS.index(m.group("small")))
    v = _TENS[m.group("tens")]
    if m.group("unit"):
        v += _UNITS.index(m.group("unit"))
    return str(v)


def normalise(text: str) -> str:
    """Lower case, single spaces, number words as digits, "zig-zag" as "zigzag"."""
    t = " ".join(text.lower().split())
    t = re.sub(r"\bzig[\s-]?zag\b", "zigzag", t)
    t = re.sub(r"\btwice\b", "2 times", t)
    t = re.sub(r"\bonce\b", "1 times", t)
    return _NUMBER_WORDS.sub(_words_to_digits, t)


def _first(pattern: str, text: str) -> re.Match[str] | None:
    return re.search(pattern, text)


def _number(pattern: str, text: str) -> float | None:
    m = _first(pattern, text)
    return float(m.group(1)) if m else None


def _altitude(t: str) -> float | None:
    for p in (
        r"\b(?:altitude|height)\s*(?:of\s*)?(" + NUM + ")" + _M,
        r"\bat\s*(?:an?\s*)?(?:altitude|height)?\s*(?:of\s*)?(" + NUM + ")" + _M + r"(?!\s*(?:radius|spacing|apart))",
        r"(" + NUM + ")" + _M + r"\s*(?:high|altitude|height|agl|above ground)",
    ):
        v = _number(p, t)
        if v is not None:
            return v
    return None


def _spacing(t: str) -> float | None:
    for p in (
        r"(" + NUM + ")" + _M + r"\s*(?:spacing|apart|between (?:lanes|lines|rows))",
        r"\b(?:spacing|spaced|lanes?|lines?|every)\s*(?:of\s*)?(" + NUM + ")" + _M,
    ):
        v = _number(p, t)
        if v is not None:
            return v
    return None


def _vehicles(t: str, ctx: FleetContext, selection: Any) -> Any:
    if re.search(
        r"\b(?:all|every|each)\s*(?:the\s*|of\s*the\s*)?(?:drones?|vehicles?|uavs?|quads?|quadrotors?|robots?|"
        r"aircraft|of them)\b|\b(?:the\s*)?(?:whole\s*|entire\s*)?fleet\b|\beveryone\b|\beverybody\b",
        t,
    ):
        return "all"
    found: list[str] = []
    lower = {n.lower(): n for n in ctx.names}
    for m in re.finditer(r"\b([a-z][a-z0-9_-]*)\b", t):
        if m.group(1) in lower and lower[m.group(1)] not in found:
            found.append(lower[m.group(1)])
    for m in re.finditer(r"\b(uav|drone|vehicle|quad|quadrotor|copter|robot)\s*[-_#]?\s*(\d+)\b", t):
        token = f"{m.group(1)}{m.group(2)}"
        if token in lower:
            continue  # named exactly, found above
        same = [n for n in ctx.names if re.fullmatch(r"[A-Za-z_-]*0*" + str(int(m.group(2))), n)]
        if len(same) != 1:
            raise MissionRequestError(f"unknown vehicle {m.group(0)!r}: the fleet has {', '.join(ctx.names)}")
        if same[0] not in found:
            found.append(same[0])
    if found:
        return found
    return list(selection) if selection else "all"


def _area(t: str, ctx: FleetContext) -> str | None:
    if re.search(r"\b(?:this|the|that|selected|my)\s*(?:selected\s*)?(?:polygon|area|region|selection|zone)\b", t):
        return "selection"
    for name in sorted(ctx.fields, key=len, reverse=True):
        if re.search(r"\b" + re.escape(name.lower()) + r"\b", t):
            return name
    if re.search(r"\bfield\b", t):
        raise MissionRequestError(f"no field of that name: the known fields are {', '.join(ctx.fields) or 'none'}")
    return None


def _tuples(t: str, n: int) -> list[list[float]]:
    inner = r"\s*,\s*".join([r"(" + NUM + r")"] * n)
    return [[float(g) for g in m.groups()] for m in re.finditer(r"[(\[]\s*" + inner + r"\s*[)\]]", t)]


def request_to_data(text: str, fleet: Any = None, selection: Any = None) -> dict[str, Any]:
    """The data form of ``text`` (see the module doc); ``selection`` the selected vehicles (used when the sentence
    names none)."""
    if not isinstance(text, str):
        raise MissionRequestError(f"a mission request must be text, got {type(text).__name__}")
    if len(text) > 2000:
        raise MissionRequestError(f"a mission request must be at most 2000 characters, got {len(text)}")
    ctx = FleetContext.of(fleet)
    t = normalise(text)
    if not t:
        raise MissionRequestError("the mission request is empty")

    if re.search(
        r"\b(?:go|come|fly|head|return|get)\s*(?:back\s*)?(?:to\s*)?(?:the\s*)?(?:home|launch|base)\b|\brtl\b"
        r"|\breturn to (?:launch|home|base)\b|\bgo back\b",
        t,
    ):
        return {"mission": "go_home", "vehicles": _vehicles(t, ctx, selection)}

    if re.search(r"\bformation\b|\bline abreast\b|\bin (?:a )?(?:wedge|v|column|single file)\b", t):
        if re.search(r"\b(?:column|file|trail|in[- ]line|one behind the other)\b", t):
            shape = "column"
        elif re.search(r"\b(?:line|abreast|side by side)\b", t):
            shape = "line"
        else:
            shape = "wedge"
        path = _tuples(t, 3)
        if not path:
            alt = _altitude(t)
            path = [[x, y, alt if alt is not None else ctx.default_altitude] for x, y in _tuples(t, 2)]
        if len(path) < 2:
            raise MissionRequestError("a formation flight needs its path: at least two points (x, y) or (x, y, z)")
        return {
            "mission": "formation",
            "path": path,
            "shape": shape,
            "spacing": _spacing(t),
            "vehicles": _vehicles(t, ctx, selection),
        }

    if re.search(r"\b(?:zigzag|lawn\s*mower|boustrophedon|serpentine)\b", t):
        rows = per_row = None
        m = _first(r"\b(\d+)\s*(?:x|by|×)\s*(\d+)\b", t)
        if m:
            rows, per_row = int(m.group(1)), int(m.group(2))
        r = _number(r"\b(\d+)\s*(?:rows?|lines?|lanes?|passes|legs)\b", t)
        rows = int(r) if r is not None else rows
        p = _number(r"\b(\d+)\s*(?:waypoints?|points?|wps?|stops?)\b", t)
        per_row = int(p) if p is not None else per_row
        if rows is None:
            raise MissionRequestError("a zigzag needs its number of rows (e.g. 'with 3 rows')")
        if per_row is None:
            raise MissionRequestError("a zigzag needs the waypoints per row (e.g. 'each row containing 5 waypoints')")
        return {
            "mission": "zigzag",
            "rows": rows,
            "per_row": per_row,
            "altitude": _altitude(t),
            "area": _area(t, ctx),
            "spacing": _spacing(t),
            "vehicles": _vehicles(t, ctx, selection),
        }

    if re.search(r"\b(?:orbit|circle|loiter)\b", t):
        centres = _tuples(t, 2)
        if not centres:
            raise MissionRequestError("an orbit needs its centre as (x, y) in metres, e.g. 'orbit (4, 2)'")
        radius = _number(r"(" + NUM + ")" + _M + r"\s*radius\b", t)
        if radius is None:
            radius = _number(r"\bradius\s*(?:of\s*)?(" + NUM + r")(?!\s*(?:times|laps?|turns|loops|rounds)\b)", t)
        if radius is None:
            raise MissionRequestError("an orbit needs its radius, e.g. 'at radius 3 m'")
        laps = _number(r"\b(\d+)\s*(?:laps?|times|turns|loops|rounds)\b", t)
        return {
            "mission": "orbit",
            "center": centres[0],
            "radius": radius,
            "altitude": _altitude(t),
            "laps": int(laps) if laps is not None else None,
            "vehicles": _vehicles(t, ctx, selection),
        }

    if re.search(r"\b(?:survey|cover|scan|map|mow|sweep)\b", t):
        area = _area(t, ctx)
        if area is None:
            if len(ctx.fields) == 1:
                area = next(iter(ctx.fields))
            else:
                area = "selection"
        return {
            "mission": "survey",
            "area": area,
            "spacing": _spacing(t),
            "altitude": _altitude(t),
            "vehicles": _vehicles(t, ctx, selection),
        }

    if re.search(r"\b(?:fly to|go to|goto|visit|waypoints?|head to|move to)\b", t):
        points = _tuples(t, 3)
        if not points:
            flat = _tuples(t, 2)
            if not flat:
                raise MissionRequestError("waypoints need positions as (x, y, z) or (x, y) in metres")
            alt = _altitude(t)
            points = [[x, y, alt if alt is not None else ctx.default_altitude] for x, y in flat]
        return {"mission": "waypoints", "points": points, "vehicles": _vehicles(t, ctx, selection)}

    raise GrammarMiss(
        f"{text.strip()[:120]!r} is not one of the built-in phrases (zigzag, orbit, survey, go home, fly to)"
    )

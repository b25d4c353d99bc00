"""Area coverage split between vehicles: the polygon is swept by parallel lanes ``spacing`` apart (a sensor
footprint ``spacing`` wide covers it), the lanes are grouped into one contiguous band per vehicle so that the longest
group is as short as possible (the linear partition problem, solved exactly by dynamic programming), each band is
that vehicle's cell (the polygon clipped between the midlines of neighbouring lanes: the cells cover the polygon
without overlap) and each vehicle flies its cell's lanes back and forth (boustrophedon, Choset 2000). Cells go to
vehicles by the assignment that minimises the summed distance from the vehicles' homes to their cells' starts
(Hungarian method), and each vehicle starts at the corner of its cell nearest its home.

Lanes run along ``heading`` [rad, ENU, from east]; by default along whichever edge of the polygon (or its
perpendicular) gives the shortest longest share, the longest edge first among equals. A lane that crosses a non-convex polygon in several pieces is flown piece by piece, the transit between
pieces straight across the gap.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from .fleet_polygon import Polygon, check_polygon, clip_band

__all__ = ["CoverageCell", "crossings", "fewest_lanes", "lanes", "path_length", "plan_coverage", "sweep_frame"]

_LANE_BLOCK = 1024
"""Lanes intersected with the polygon's edges at once (a block is ``_LANE_BLOCK`` x vertices floats)."""


@dataclass(frozen=True)
class CoverageCell:
    """One vehicle's share of a coverage: its cell of the polygon and the boustrophedon path over it."""

    vehicle: str
    polygon: Polygon
    """The cell ``((x, y), ...)`` [m]."""
    path: tuple[tuple[float, float, float], ...]
    """Waypoints ENU [m]: the ends of each lane piece, in flying order, at the survey altitude."""
    lanes: int
    """How many lanes the cell holds."""

    @property
    def length(self) -> float:
        """Length of the path [m]."""
        return path_length(np.asarray(self.path))


def path_length(path: np.ndarray) -> float:
    """Length of a polyline ((N, D) array) [m]."""
    p = np.asarray(path, dtype=float)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def lanes(
    polygon: ArrayLike, spacing: float, heading: float | None = None
) -> tuple[np.ndarray, list[list[tuple[float, float]]], np.ndarray, np.ndarray]:
    """The sweep of ``polygon``: ``(offsets, pieces, u, w)`` with ``u`` the lane direction, ``w`` the sweep
    direction (unit vectors), ``offsets[k]`` lane k's position along ``w`` [m] and ``pieces[k]`` its ``(s0, s1)``
    intervals along ``u`` inside the polygon. The first and last lanes lie ``spacing / 2`` inside the polygon's
    extent along ``w`` and the lanes are evenly spaced at most ``spacing`` apart."""
    poly = np.asarray(polygon, dtype=float)
    u, w = sweep_frame(poly, heading)
    pw = poly @ w
    lo, hi = float(pw.min()), float(pw.max())
    width = hi - lo
    n = _lane_count(width, spacing)
    if n == 1:
        offsets = np.array([0.5 * (lo + hi)])
    else:
        offsets = lo + 0.5 * spacing + np.arange(n) * (width - spacing) / (n - 1)
    return offsets, crossings(poly, u, w, offsets), u, w


def crossings(polygon: ArrayLike, u: np.ndarray, w: np.ndarray, offsets: np.ndarray) -> list[list[tuple[float, float]]]:
    """For each line ``w . p = offsets[k]`` across ``polygon``, its ``(s0, s1)`` intervals along ``u`` inside the
    polygon, in ascending order (several where it crosses a non-convex polygon more than once)."""
    poly = np.asarray(polygon, dtype=float)
    pw, pu = poly @ w, poly @ u
    pieces: list[list[tuple[float, float]]] = []
    wa, wb = pw, np.roll(pw, -1)  # edge k runs from vertex k to k + 1
    ua, ub = pu, np.roll(pu, -1)
    for c in np.array_split(offsets, max(1, len(offsets) // _LANE_BLOCK)):  # lines x edges, in bounded blocks
        c = c[:, None]
        cross = (wa > c) != (wb > c)
        with np.errstate(divide="ignore", invalid="ignore"):
            at = ua + (c - wa) / (wb - wa) * (ub - ua)  # where each edge crosses each line, along u
        for row, hit in zip(at, cross, strict=True):
            s = np.sort(row[hit]).tolist()
            pieces.append([(s[k], s[k + 1]) for k in range(0, len(s) - 1, 2) if s[k + 1] - s[k] > 1e-9])
    return pieces


def _lane_count(width: float, spacing: float) -> int:
    return max(1, math.ceil(width / spacing - 1e-9))


def fewest_lanes(polygon: ArrayLike, spacing: float) -> int:
    """The fewest lanes any sweep :func:`plan_coverage` tries (along an edge or its perpendicular) needs: each lane
    is at least two waypoints, so a coverage of ``polygon`` has at least twice as many (a bound that costs no
    sweep)."""
    poly = np.asarray(polygon, dtype=float)
    return min(_lane_count(float(np.ptp(poly @ sweep_frame(poly, th)[1])), spacing) for th in _headings(poly))


def sweep_frame(polygon: ArrayLike, heading: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(u, w)``: the lane direction along ``heading`` [rad] (default: the polygon's longest edge) and the sweep
    direction across it (unit vectors), as :func:`lanes` uses them."""
    th = _headings(np.asarray(polygon, dtype=float))[0] if heading is None else float(heading)
    return np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])


def _headings(poly: np.ndarray) -> list[float]:
    """Lane directions worth trying: along the longest edge first, then every edge and its perpendicular."""
    edges = np.roll(poly, -1, axis=0) - poly
    order = np.argsort(-np.linalg.norm(edges, axis=1), kind="stable")
    out: list[float] = []
    for k in order:
        th = math.atan2(edges[k, 1], edges[k, 0])
        for t in (th, th + 0.5 * math.pi):
            t = math.remainder(t, math.pi)
            if all(abs(math.remainder(t - o, math.pi)) > 1e-9 for o in out):
                out.append(t)
    return out


def _partition(costs: np.ndarray, gaps: np.ndarray, parts: int) -> tuple[list[tuple[int, int]], float]:
    """Contiguous groups ``[(first, last), ...]`` of the lanes minimising the largest group cost (a group costs its
    lanes plus the gaps between them), and that largest cost."""
    n = len(costs)
    pre = np.concatenate([[0.0], np.cumsum(costs)])
    pre_gap = np.concatenate([[0.0], np.cumsum(gaps)])  # gaps[k]: lane k -> k + 1

    best = np.full((parts + 1, n + 1), math.inf)
    cut = np.zeros((parts + 1, n + 1), dtype=int)
    best[0, 0] = 0.0
    for p in range(1, parts + 1):
        for j in range(p, n + 1):  # the first j lanes in p groups
            first = np.arange(p - 1, j)  # the last group is lanes first..j-1
            v = np.maximum(best[p - 1, first], pre[j] - pre[first] + pre_gap[j - 1] - pre_gap[first])
            k = int(np.argmin(v))  # the first of the best
            best[p, j], cut[p, j] = v[k], first[k]
    groups = []
    j = n
    for p in range(parts, 0, -1):
        i = int(cut[p, j])
        groups.append((i, j - 1))
        j = i
    return groups[::-1], float(best[parts, n])


def _sweep(pieces: list[list[tuple[float, float]]], offsets: np.ndarray, u: np.ndarray, w: np.ndarray,
           first: int, last: int, reverse: bool, flip: bool) -> np.ndarray:  # fmt: skip
    order = range(last, first - 1, -1) if reverse else range(first, last + 1)
    pts = []
    forward = not flip
    for k in order:
        segs = pieces[k] if forward else [(b, a) for a, b in reversed(pieces[k])]
        for a, b in segs:
            pts += [a * u + offsets[k] * w, b * u + offsets[k] * w]
        forward = not forward
    return np.asarray(pts)


def plan_coverage(
    polygon: ArrayLike,
    homes: Mapping[str, ArrayLike],
    spacing: float,
    altitude: float,
    heading: float | None = None,
    max_lanes: int | None = None,
) -> dict[str, CoverageCell]:
    """Split the coverage of ``polygon`` between the vehicles of ``homes`` (name -> home ``(x, y[, z])`` [m]); see
    the module doc. ``max_lanes``: sweeps of more lanes are not tried (their paths would be too long to fly anyway;
    default: all are). ``ValueError`` names what is wrong (a bad polygon, spacing or altitude, more vehicles than
    lanes, no sweep within ``max_lanes``)."""
    poly = np.asarray(check_polygon(polygon), dtype=float)
    for name, v in (("spacing", spacing), ("altitude", altitude)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be a finite number > 0 [m], got {v!r}")
    if heading is not None and (isinstance(heading, bool) or not math.isfinite(heading)):
        raise ValueError(f"heading must be a finite angle [rad] or None, got {heading!r}")
    names = list(homes)
    if not names:
        raise ValueError("coverage needs at least one vehicle")
    candidates = _headings(poly) if heading is None else [float(heading)]
    best = None
    too_many = 0
    for th in candidates:  # the sweep whose longest share is shortest (ties: the first, along the longest edge)
        pw = poly @ sweep_frame(poly, th)[1]
        if max_lanes is not None and _lane_count(float(pw.max() - pw.min()), spacing) > max_lanes:
            too_many += 1  # not swept at all: a sliver's sweep across it would be millions of lanes
            continue
        offsets, pieces, u, w = lanes(poly, float(spacing), th)
        keep = [k for k, p in enumerate(pieces) if p]
        offsets, pieces = offsets[keep], [pieces[k] for k in keep]
        if len(pieces) < len(names):
            continue
        costs = np.array([p[-1][1] - p[0][0] for p in pieces])
        gaps = np.abs(np.diff(offsets))
        groups, makespan = _partition(costs, gaps, len(names))
        if best is None or makespan < best[0] - 1e-9:
            best = (makespan, offsets, pieces, u, w, groups)
    if best is None and too_many == len(candidates):
        raise ValueError(f"every sweep of the area at lane spacing {spacing} m needs more than {max_lanes} lanes")
    if best is None:
        raise ValueError(f"the area is too narrow for {len(names)} vehicles at lane spacing {spacing} m")
    _, offsets, pieces, u, w, groups = best

    variants = [
        [_sweep(pieces, offsets, u, w, i, j, rev, flip) for rev in (False, True) for flip in (False, True)]
        for i, j in groups
    ]
    home_xy = np.array([np.asarray(homes[n], dtype=float)[:2] for n in names])
    dist = np.array([[min(np.linalg.norm(v[0] - h) for v in var) for var in variants] for h in home_xy])
    rows, cols = linear_sum_assignment(dist)
    out: dict[str, CoverageCell] = {}
    for r, g in zip(rows, cols, strict=True):
        name = names[r]
        i, j = groups[g]
        path = min(variants[g], key=lambda v: float(np.linalg.norm(v[0] - home_xy[r])))
        lo = -math.inf if i == 0 else 0.5 * (offsets[i - 1] + offsets[i])
        hi = math.inf if j == len(offsets) - 1 else 0.5 * (offsets[j] + offsets[j + 1])
        out[name] = CoverageCell(
            vehicle=name,
            polygon=clip_band(poly, w, lo, hi),
            path=tuple((round(float(x), 9) + 0.0, round(float(y), 9) + 0.0, float(altitude)) for x, y in path),
            lanes=j - i + 1,
        )
    return {n: out[n] for n in names}

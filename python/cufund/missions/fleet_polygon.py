"""Planar polygons of fleet missions (fields, survey areas, geofences): validation, area, containment and clipping by
a half-plane. Vertices are world ENU ``(x, y)`` [m], in either winding; the polygon closes by itself (the last vertex
is not repeated)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["MAX_VERTICES", "Polygon", "check_polygon", "clip_band", "polygon_area", "polygon_contains"]

MAX_VERTICES = 200
"""The most vertices a mission polygon may have."""

Polygon = tuple[tuple[float, float], ...]
"""A simple polygon as ``((x, y), ...)`` [m]."""


def _segments_cross(p: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray) -> bool:
    """Whether the closed segments pq and rs share a point."""

    def orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    def on(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:  # c on segment ab, given collinear
        return min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1])

    d1, d2, d3, d4 = orient(r, s, p), orient(r, s, q), orient(p, q, r), orient(p, q, s)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    return (
        (d1 == 0 and on(r, s, p)) or (d2 == 0 and on(r, s, q)) or (d3 == 0 and on(p, q, r)) or (d4 == 0 and on(p, q, s))
    )


def check_polygon(value: Any, name: str = "polygon") -> Polygon:
    """``value`` as a :data:`Polygon`, or ``ValueError`` naming ``name`` and what is wrong: 3 to
    :data:`MAX_VERTICES` finite ``[x, y]`` pairs, no repeated vertex, no self-intersection, non-zero area."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ValueError(f"{name} must be a list of [x, y] vertices [m], got {type(value).__name__}")
    if not 3 <= len(value) <= MAX_VERTICES:
        raise ValueError(f"{name} must have 3 to {MAX_VERTICES} vertices, got {len(value)}")
    out = []
    for i, v in enumerate(value):
        if isinstance(v, (str, bytes)) or not isinstance(v, Sequence) or len(v) != 2:
            raise ValueError(f"{name}[{i}] must be [x, y] [m], got {v!r}")
        xy = []
        for c in v:
            try:
                f = float(c) if isinstance(c, (int, float)) and not isinstance(c, bool) else math.nan
            except OverflowError:
                f = math.nan
            if not math.isfinite(f) or abs(f) > 1e6:
                raise ValueError(f"{name}[{i}] must hold finite numbers within 1000 km [m], got {str(v)[:60]}")
            xy.append(f)
        out.append((xy[0], xy[1]))
    if len(set(out)) != len(out):
        raise ValueError(f"{name} repeats a vertex")
    pts = np.asarray(out)
    n = len(pts)
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue  # neighbouring edges share a vertex
            if _segments_cross(pts[i], pts[(i + 1) % n], pts[j], pts[(j + 1) % n]):
                raise ValueError(f"{name} intersects itself (edges {i} and {j})")
    if polygon_area(out) < 1e-6:
        raise ValueError(f"{name} has no area")
    return tuple(out)


def polygon_area(polygon: ArrayLike) -> float:
    """Unsigned area [m^2] (shoelace formula)."""
    p = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(p) < 3:
        return 0.0
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def polygon_contains(polygon: ArrayLike, xy: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Whether each point of ``xy`` ((N, 2) or (2,)) lies inside or on the boundary of ``polygon`` (crossing number,
    with points within ``tol`` [m] of an edge counted inside)."""
    pts = np.atleast_2d(np.asarray(xy, dtype=float))[:, :2]
    poly = np.asarray(polygon, dtype=float)
    a, b = poly, np.roll(poly, -1, axis=0)
    inside = np.zeros(len(pts), dtype=bool)
    on_edge = np.zeros(len(pts), dtype=bool)
    for (ax, ay), (bx, by) in zip(a, b, strict=True):
        px, py = pts[:, 0], pts[:, 1]
        crosses = (ay > py) != (by > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = ax + (py - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (px < x_at)
        ex, ey = bx - ax, by - ay
        L2 = ex * ex + ey * ey
        s = np.clip(((px - ax) * ex + (py - ay) * ey) / L2, 0.0, 1.0) if L2 > 0 else np.zeros_like(px)
        on_edge |= np.hypot(px - (ax + s * ex), py - (ay + s * ey)) <= tol
    return inside | on_edge


def _clip_half_plane(poly: list[tuple[float, float]], n: np.ndarray, c: float) -> list[tuple[float, float]]:
    """Sutherland–Hodgman: the part of ``poly`` where ``n . p <= c``."""
    out: list[tuple[float, float]] = []
    m = len(poly)
    for i in range(m):
        p, q = np.asarray(poly[i]), np.asarray(poly[(i + 1) % m])
        dp, dq = float(n @ p) - c, float(n @ q) - c
        if dp <= 0:
            out.append((float(p[0]), float(p[1])))
        if (dp < 0 < dq) or (dq < 0 < dp):
            s = dp / (dp - dq)
            r = p + s * (q - p)
            out.append((float(r[0]), float(r[1])))
    return out


def clip_band(polygon: ArrayLike, direction: np.ndarray, lo: float, hi: float) -> Polygon:
    """The part of ``polygon`` where ``lo <= direction . p <= hi`` (``direction`` a unit vector); empty when they do
    not meet. Exact for convex polygons; for a non-convex one the pieces may be joined by zero-area edges along the
    band's border (its area is still exact)."""
    d = np.asarray(direction, dtype=float)
    poly = [(float(x), float(y)) for x, y in np.asarray(polygon, dtype=float).reshape(-1, 2)]
    if math.isfinite(hi):
        poly = _clip_half_plane(poly, d, hi)
    if poly and math.isfinite(lo):
        poly = _clip_half_plane(poly, -d, -lo)
    return tuple(poly) if len(poly) >= 3 else ()

"""Triangle meshes of primitive shapes: (vertices (V, 3) float64 [m], triangles (T, 3) int64).

Every mesh is closed and its triangles are wound counter-clockwise seen from outside, so
geometric normals point outwards. Shapes are centred at the origin, axis-aligned, z up.
"""

from __future__ import annotations

import numpy as np

Mesh = tuple[np.ndarray, np.ndarray]


def _positive(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a finite number > 0 [m], got {value!r}")
    value = float(value)
    if not np.isfinite(value) or value <= 0.0:
        raise ValueError(f"{name} must be a finite number > 0 [m], got {value}")
    return value


def _count(name: str, value: object, lo: int, hi: int, limit: str = "") -> int:
    """An integer in [lo, hi]; ``limit`` names the cufund.core.limits field that sets hi."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if not lo <= int(value) <= hi:
        hint = f" ({limit} = {hi}; raise it with cufund.core.limits.configure({limit}=...))" if limit else ""
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value}{hint}")
    return int(value)


def box(size: tuple[float, float, float]) -> Mesh:
    """Box of edge lengths ``size`` = (sx, sy, sz) [m]."""
    if isinstance(size, (str, bytes)) or not hasattr(size, "__len__") or len(size) != 3:
        raise ValueError(f"size must have 3 entries (sx, sy, sz) [m], got {size!r}")
    h = np.array([_positive(f"size[{i}]", s) for i, s in enumerate(size)]) / 2.0
    corners = np.array([[(i & 1) * 2 - 1, ((i >> 1) & 1) * 2 - 1, ((i >> 2) & 1) * 2 - 1] for i in range(8)], float)
    tris = np.array(
        [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ],
        np.int64,
    )
    return corners * h, tris


def plane(size: tuple[float, float]) -> Mesh:
    """Rectangle of ``size`` = (sx, sy) [m] in the z = 0 plane, normal +z (two triangles)."""
    if isinstance(size, (str, bytes)) or not hasattr(size, "__len__") or len(size) != 2:
        raise ValueError(f"size must have 2 entries (sx, sy) [m], got {size!r}")
    hx, hy = _positive("size[0]", size[0]) / 2.0, _positive("size[1]", size[1]) / 2.0
    v = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    return v, np.array([[0, 1, 2], [0, 2, 3]], np.int64)


def cylinder(radius: float, height: float, segments: int = 32) -> Mesh:
    """Capped cylinder about the z axis, from z = -height/2 to +height/2."""
    from cufund.core.limits import current

    r, h = _positive("radius", radius), _positive("height", height)
    n = _count("segments", segments, 3, current().mesh_max_segments, "mesh_max_segments")
    a = 2.0 * np.pi * np.arange(n) / n
    ring = np.stack([r * np.cos(a), r * np.sin(a)], 1)
    bottom = np.column_stack([ring, np.full(n, -h / 2)])
    top = np.column_stack([ring, np.full(n, h / 2)])
    v = np.vstack([bottom, top, [[0.0, 0.0, -h / 2], [0.0, 0.0, h / 2]]])
    i = np.arange(n)
    j = (i + 1) % n
    side = np.concatenate([np.stack([i, j, n + i], 1), np.stack([j, n + j, n + i], 1)])
    caps = np.concatenate([np.stack([np.full(n, 2 * n), j, i], 1), np.stack([np.full(n, 2 * n + 1), n + i, n + j], 1)])
    return v, np.concatenate([side, caps]).astype(np.int64)


def sphere(radius: float, subdivisions: int = 3) -> Mesh:
    """Icosphere: an icosahedron subdivided ``subdivisions`` times, vertices on the sphere."""
    r = _positive("radius", radius)
    subdivisions = _count("subdivisions", subdivisions, 0, 7)
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array(
        [
            [-1, t, 0],
            [1, t, 0],
            [-1, -t, 0],
            [1, -t, 0],
            [0, -1, t],
            [0, 1, t],
            [0, -1, -t],
            [0, 1, -t],
            [t, 0, -1],
            [t, 0, 1],
            [-t, 0, -1],
            [-t, 0, 1],
        ],
        float,
    )
    f = np.array(
        [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ],
        np.int64,
    )
    verts = list(v / np.linalg.norm(v, axis=1, keepdims=True))
    for _ in range(int(subdivisions)):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int, cache: dict[tuple[int, int], int] = cache) -> int:  # this subdivision's cache
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = np.array(nf, np.int64)
    return np.array(verts) * r, f


def tunnel_frame(width: float, height: float, depth: float, thickness: float) -> Mesh:
    """Rectangular frame (a door with four bars) around an opening ``width`` (y) × ``height`` (z),
    ``depth`` along x, bars ``thickness`` thick; the opening is centred at the origin."""
    w, h = _positive("width", width), _positive("height", height)
    d, th = _positive("depth", depth), _positive("thickness", thickness)
    parts = []
    ow = w + 2 * th  # outer width: the top and bottom bars span the posts
    for size, centre in [
        ((d, ow, th), (0, 0, (h + th) / 2)),
        ((d, ow, th), (0, 0, -(h + th) / 2)),
        ((d, th, h), (0, (w + th) / 2, 0)),
        ((d, th, h), (0, -(w + th) / 2, 0)),
    ]:
        v, f = box(size)
        parts.append((v + np.asarray(centre, float), f))
    return merge(parts)


def merge(parts: list[Mesh]) -> Mesh:
    """One mesh from several (indices offset)."""
    vs, fs, off = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.vstack(vs), np.vstack(fs)

"""Tunnel frames from a point cloud (paper §3.2, Fig. 9), as pure functions testable without a simulator.

:func:`detect_frames` crops the cloud (the floor band, above ``ceiling_z``, outside the region of interest),
reduces it to voxel means, and segments it with DBSCAN (Open3D's labelling, in C++) above the floor, leaving out x-y columns that
reach higher than any frame (walls, poles). In each cluster it fits a vertical plane (deterministic RANSAC on
a line in the horizontal plane, scored by the length its inliers cover, refined by PCA); frames close enough
to share a cluster are taken plane by plane. The frame's own points are then gathered from the whole cloud in
a slab around that plane (the floor cut would otherwise hide a bottom bar standing on the floor), keeping the
returns whose rays met the plane squarely when the sensor positions are known (a grazing return carries its
range noise into the plane), and split into the four bars in plane coordinates (u across, horizontal; v up).
Each bar's centre line is the midpoint of robust percentile extents across the bar (``percentile`` and
``100 - percentile``), which points missing along the bar (an occluder, a shadow) and points on its side faces
do not move; a bottom bar merged with the floor is located by its upper edge instead. The opening is the hole
between the bars' inner edges: its centre is halfway between the posts and between the top and bottom bars,
its width and height the distances between the bars' centre lines less one bar thickness. Its depth along the
normal is the median of the bars' points, each moved half a bar away from the side its ray came from.

The paper takes the mean of each cluster's points instead; :attr:`FrameDetection.cluster_mean_W` keeps that
estimate for comparison (it moves towards the visible side when a bar is partly hidden).

Clusters that are not frames (walls, the floor, a pad, boxes) are rejected: the in-plane extent must fit an
opening between ``min_opening`` and ``max_opening``, the cluster must be thin across its plane, every bar
must hold enough points and the opening must be empty; detections closer than ``min_separation`` are one.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import overload

import numpy as np

from cufund import _core

__all__ = [
    "FrameDetection",
    "TunnelDetectorParams",
    "column_keys",
    "detect_frames",
    "detect_in_voxels",
    "order_along_course",
    "voxel_keys",
    "voxel_means",
]


def _positive(name: str, v: object, allow_zero: bool = False) -> float:
    if (
        isinstance(v, bool)
        or not isinstance(v, numbers.Real)
        or not math.isfinite(v)
        or (v < 0 if allow_zero else v <= 0)
    ):
        raise ValueError(
            f"TunnelDetectorParams.{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {v!r}"
        )
    return float(v)


@dataclass(frozen=True)
class TunnelDetectorParams:
    """Detection of tunnel frames (:func:`detect_frames`) and the detector component's bookkeeping.
    Lengths [m], rates [Hz]."""

    voxel: float = 0.02
    """Edge of the voxels whose mean points are measured [m]."""
    cluster_voxel: float = 0.04
    """Edge of the coarser voxels clustered by DBSCAN [m]."""
    eps: float = 0.12
    """DBSCAN neighbourhood radius [m] (bars of one frame must join, frames must stay apart)."""
    min_points: int = 4
    """DBSCAN core point threshold (neighbours within ``eps``, the point included)."""
    floor_z: float = 0.0
    """Height of the floor in the (estimated) world frame [m]."""
    floor_band: float = 0.02
    """Points lower than floor_z + floor_band are taken for the floor and dropped (a bottom bar standing on the
    floor keeps its upper part; the floor would otherwise fill most of an accumulated map) [m]."""
    floor_cut: float = 0.1
    """Points lower than floor_z + floor_cut are not clustered (they are still measured) [m]."""
    ceiling_z: float = 3.0
    """Points higher than this are ignored [m]."""
    max_frame_top: float = 2.6
    """No frame reaches above this: 10 cm x-y columns holding points between it and ceiling_z (walls, poles) are
    not clustered, nor accumulated by the component; ceiling_z must stay below the ceiling [m]."""
    roi_min_W: tuple[float, float, float] | None = None
    """Lower corner of the region of interest (e.g. inside the arena's walls) [m]; None: unbounded."""
    roi_max_W: tuple[float, float, float] | None = None
    """Upper corner of the region of interest [m]; None: unbounded."""
    bar: float = 0.05
    """Thickness of the frames' bars, in the frame's plane [m]."""
    percentile: float = 5.0
    """Robust extent of a bar across its width: from this percentile to 100 - this [%]."""
    slab: float = 0.08
    """Half-depth of the slab around a frame's plane whose points belong to the frame [m]."""
    min_incidence: float = 0.5
    """With ray directions known, a frame's points whose ray met its plane at |cos| below this (grazing, their
    range noise lying in the plane) are not measured."""
    min_opening: float = 0.2
    """Smallest opening width or height accepted [m]."""
    max_opening: float = 2.5
    """Largest opening width or height accepted [m]."""
    max_thickness: float = 0.15
    """Largest spread of a cluster across its plane (10th to 90th percentile) [m]."""
    min_separation: float = 0.25
    """Centres closer than this are one frame (the best supported detection stays) [m]."""
    min_bar_points: int = 6
    """Fewest points on each bar for a frame to be reported."""
    max_hole_fraction: float = 0.05
    """Largest fraction of a frame's points inside its opening (a box or a wall has no hole)."""
    ransac_iterations: int = 64
    """Deterministic RANSAC draws for each cluster's plane."""
    # --- the component ---------------------------------------------------------------------------------
    rate_hz: float = 2.0
    """How often the component re-detects on its accumulated map [Hz]."""
    settled_rate_hz: float = 1.0
    """How often once every expected frame is confidently tracked [Hz] (at most rate_hz)."""
    point_stride: int = 1
    """The component accumulates every point_stride-th point of each scan (1: all; a Mid-360 gives 200 000/s)."""
    max_range: float = 10.0
    """Points farther than this from the LiDAR are not accumulated [m]."""
    max_voxels: int = 150_000
    """Bound of the accumulated voxel map; the least recently seen voxels go first."""
    associate_radius: float = 0.3
    """A detection continues the track whose centre is nearest, within this [m]."""
    full_support: int = 400
    """Points on a frame for full support (confidence grows with points and repeated detections)."""
    seed: int = 0
    """Seed of the RANSAC draws (same seed, same cloud: the same detections)."""

    def __post_init__(self) -> None:
        for name in (
            "voxel",
            "cluster_voxel",
            "eps",
            "bar",
            "slab",
            "min_opening",
            "max_opening",
            "max_thickness",
            "min_separation",
            "rate_hz",
            "settled_rate_hz",
            "max_range",
            "associate_radius",
        ):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        object.__setattr__(self, "floor_cut", _positive("floor_cut", self.floor_cut, allow_zero=True))
        object.__setattr__(self, "floor_band", _positive("floor_band", self.floor_band, allow_zero=True))
        inc = _positive("min_incidence", self.min_incidence, allow_zero=True)
        if not inc < 1:
            raise ValueError(f"TunnelDetectorParams.min_incidence must be in [0, 1), got {inc}")
        for name in ("floor_z", "ceiling_z", "max_frame_top"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ValueError(f"TunnelDetectorParams.{name} must be a finite number [m], got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.ceiling_z <= self.floor_z + self.floor_cut:
            raise ValueError(f"TunnelDetectorParams.ceiling_z must be above floor_z + floor_cut, got {self.ceiling_z}")
        for name in ("roi_min_W", "roi_max_W"):
            v = getattr(self, name)
            if v is not None:
                a = np.asarray(v, dtype=float) if not isinstance(v, str) else np.zeros(0)
                if a.shape != (3,) or not np.all(np.isfinite(a)):
                    raise ValueError(f"TunnelDetectorParams.{name} must be None or 3 finite numbers [m], got {v!r}")
                object.__setattr__(self, name, tuple(float(x) for x in a))
        if (
            self.roi_min_W is not None
            and self.roi_max_W is not None
            and not all(lo < hi for lo, hi in zip(self.roi_min_W, self.roi_max_W, strict=True))
        ):
            raise ValueError(
                f"TunnelDetectorParams.roi_min_W must be below roi_max_W, got {self.roi_min_W} and {self.roi_max_W}"
            )
        for name in (
            "min_points",
            "min_bar_points",
            "ransac_iterations",
            "max_voxels",
            "full_support",
            "seed",
            "point_stride",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < (0 if name == "seed" else 1):
                raise ValueError(
                    f"TunnelDetectorParams.{name} must be an integer >= {0 if name == 'seed' else 1}, got {v!r}"
                )
            object.__setattr__(self, name, int(v))
        p = _positive("percentile", self.percentile)
        if not p < 50:
            raise ValueError(f"TunnelDetectorParams.percentile must be in (0, 50) [%], got {p}")
        h = _positive("max_hole_fraction", self.max_hole_fraction, allow_zero=True)
        if not h < 1:
            raise ValueError(f"TunnelDetectorParams.max_hole_fraction must be in [0, 1), got {h}")
        if self.max_opening <= self.min_opening:
            raise ValueError("TunnelDetectorParams.max_opening must be > min_opening")


@dataclass(frozen=True)
class FrameDetection:
    """One detected frame, in the frame of the input points."""

    centre_W: np.ndarray
    """(3,) centre of the opening [m]."""
    normal_W: np.ndarray
    """(3,) unit normal of the frame's (vertical) plane; :func:`detect_frames` points it along the course."""
    width: float
    """Opening width, horizontal in the plane [m]."""
    height: float
    """Opening height [m]."""
    support: int
    """Points on the frame's bars (met at an incidence of at least ``min_incidence``)."""
    points_W: np.ndarray
    """(M, 3) the frame's points (its bars, measured voxel means) [m]."""
    cluster_mean_W: np.ndarray
    """(3,) the mean of the frame's points: the paper's estimate of the centre, kept for comparison [m]."""

    @property
    def opening(self) -> tuple[float, float]:
        return (self.width, self.height)


def _points(name: str, a: object) -> np.ndarray:
    p = np.asarray(a, dtype=float) if not isinstance(a, (str, bytes)) else np.zeros((0,))
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3) [m], got {getattr(p, 'shape', None)}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be finite")
    return p


def voxel_keys(points: np.ndarray, voxel: float) -> np.ndarray:
    """One int64 key per point naming its voxel of edge ``voxel`` [m] (21 bits per axis: +-1e6 voxels)."""
    idx = np.floor(points / voxel).astype(np.int64) + (1 << 20)
    if len(idx) and (idx.min() < 0 or idx.max() >= 1 << 21):
        raise ValueError(f"points must lie within {(1 << 20) * voxel:g} m of the origin for voxels of {voxel} m")
    return (idx[:, 0] << 42) | (idx[:, 1] << 21) | idx[:, 2]


@overload
def voxel_means(points: np.ndarray, voxel: float, extra: None = None) -> np.ndarray: ...


@overload
def voxel_means(points: np.ndarray, voxel: float, extra: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def voxel_means(
    points: np.ndarray, voxel: float, extra: np.ndarray | None = None
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The mean of the points in each occupied voxel of edge ``voxel`` [m], sorted by voxel (deterministic);
    with ``extra`` (N, k), also the mean of its rows per voxel."""
    if len(points) == 0:
        empty = np.zeros((0, 3))
        return empty if extra is None else (empty, np.zeros((0, extra.shape[1])))
    keys = voxel_keys(points, voxel)
    order = np.argsort(keys, kind="stable")
    k_sorted = keys[order]
    start = np.flatnonzero(np.r_[True, k_sorted[1:] != k_sorted[:-1]])
    counts = np.diff(np.r_[start, len(keys)])[:, None]
    means = np.add.reduceat(points[order], start, axis=0) / counts
    if extra is None:
        return means
    return means, np.add.reduceat(extra[order], start, axis=0) / counts


def _dbscan(points: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """Open3D's ``PointCloud.cluster_dbscan`` labels (the same labels, tested against it), computed in C++ on a
    grid of eps cells: no Open3D import (0.8 s) and no KD-tree per call."""
    return _core.perception.dbscan(np.asarray(points, dtype=float).reshape(-1, 3), eps, min_points)


def _vertical_plane(
    xy: np.ndarray, threshold: float, iterations: int, rng: np.random.Generator
) -> tuple[np.ndarray, float] | None:
    """Unit horizontal normal n (2,) and offset d (n . p = d) of the line best supported by ``xy``."""
    n_pts = len(xy)
    if n_pts < 3:
        return None
    i = rng.integers(n_pts, size=iterations)
    j = rng.integers(n_pts, size=iterations)
    d_ij = xy[j] - xy[i]
    length = np.linalg.norm(d_ij, axis=1)
    ok = length > 2 * threshold
    if not np.any(ok):
        return None
    normals = np.stack([-d_ij[ok, 1], d_ij[ok, 0]], axis=1) / length[ok, None]
    offsets = np.einsum("kj,kj->k", normals, xy[i[ok]])
    inliers = np.abs(xy @ normals.T - offsets) < threshold  # (N, K)
    # Score: the length of line the inliers cover (distinct bins along it), then their count. Vertical bars
    # project to a spot each, so counts alone would favour a line through two posts or a post and a box.
    along = np.floor((xy @ np.stack([normals[:, 1], -normals[:, 0]])) / threshold).astype(np.int64)
    covered, counts = _core.perception.line_support(along, inliers)  # distinct bins among the inliers, inliers
    best = int(np.lexsort((np.arange(len(counts))[::-1], counts, covered))[-1])  # most covered, most, first
    mask = inliers[:, best]
    for _ in range(2):  # PCA on the inliers, then the inliers of that line
        sel = xy[mask]
        if len(sel) < 3:
            return None
        c = sel.mean(axis=0)
        _, vecs = np.linalg.eigh(np.cov((sel - c).T))
        n = vecs[:, 0]
        if n[0] < 0 or (n[0] == 0 and n[1] < 0):
            n = -n
        d = float(n @ c)
        mask = np.abs(xy @ n - d) < threshold
    return n, d


def _percentiles(a: np.ndarray, qs: tuple[float, ...]) -> list[float]:
    """``np.percentile(a, qs)`` (linear interpolation) of a non-empty 1-D array, the same numbers without its
    per-call overhead (about 0.1 ms, which dominated on the few hundred points of a bar)."""
    s = np.sort(a)
    n = len(s)
    out = []
    for q in qs:
        x = (n - 1) * (q / 100)
        if x >= n - 1:
            out.append(float(s[-1]))
            continue
        i = math.floor(x)
        g = x - i
        lo, hi = float(s[i]), float(s[i + 1])
        d = hi - lo
        out.append(hi - d * (1 - g) if g >= 0.5 else lo + d * g)
    return out


def _mid(a: np.ndarray, q: float) -> float:
    lo, hi = _percentiles(a, (q, 100.0 - q))
    return 0.5 * float(lo + hi)


def _read_bars(
    u: np.ndarray, v: np.ndarray, u_lo: float, u_hi: float, v_hi: float, p: TunnelDetectorParams, need: int
) -> tuple | None:
    """The four bars of a frame from its points' plane coordinates (u across, v up): the posts' centre lines
    u_left and u_right, the top and bottom bars' v_top and v_bot, and each bar's point mask; None unless every
    bar holds ``need`` points."""
    b, q = p.bar, p.percentile
    quarter = 0.25 * (u_hi - u_lo)  # the middle half of the span: clear of the posts and their noise
    mid_u = np.abs(u - 0.5 * (u_lo + u_hi)) < quarter
    top_pts = mid_u & (v > v_hi - 2 * b)
    if top_pts.sum() < need:
        return None
    v_top = _mid(v[top_pts], q)
    # the bottom bar: the highest horizontal structure below the opening, between the posts
    below = mid_u & (v < v_top - b - p.min_opening)
    if below.sum() < need:
        return None
    edge = _percentiles(v[below], (100.0 - q,))[0]  # its upper (inner) edge, less q % of the bar
    bot_pts = below & (v > edge - 2 * b)
    if bot_pts.sum() < need:
        return None
    if edge - 1.5 * b < p.floor_z + 0.02:  # standing on the floor: the floor's points merge with its lower edge
        v_bot = edge + q / 100.0 * b - b / 2
    else:
        v_bot = _mid(v[bot_pts], q)
    # the posts, between the bars' inner edges
    rows = (v > v_bot + b) & (v < v_top - b)
    left = rows & (u < u_lo + 3 * b) & (u < 0.5 * (u_lo + u_hi))
    right = rows & (u > u_hi - 3 * b) & (u > 0.5 * (u_lo + u_hi))
    if left.sum() < need or right.sum() < need:
        return None
    return _mid(u[left], q), _mid(u[right], q), v_top, v_bot, top_pts, bot_pts, left, right


def _measure(
    cluster: np.ndarray,
    cloud: np.ndarray,
    views: np.ndarray | None,
    p: TunnelDetectorParams,
    rng: np.random.Generator,
    by_x: tuple | None = None,
) -> tuple[FrameDetection | None, np.ndarray | None]:
    """The frame on the best vertical plane through a cluster, measured on the whole cloud (None if it is not a
    frame), and which of the cluster's points lie on that plane (None without a plane)."""
    b = p.bar
    plane = _vertical_plane(cluster[:, :2], max(b, 2 * p.voxel), p.ransac_iterations, rng)
    if plane is None:
        return None, None
    n2, d = plane
    n = np.array([n2[0], n2[1], 0.0])
    u_axis = np.array([-n2[1], n2[0], 0.0])
    depth_c = cluster @ n - d
    on_plane = np.abs(depth_c) < p.slab  # an object just before the frame, or the next frame, may have joined
    return _measure_plane(cluster[on_plane], depth_c[on_plane], n, d, u_axis, cloud, views, p, by_x), on_plane


def _x_order(cloud: np.ndarray, voxel: float) -> tuple:
    """An index for x-y box queries on ``cloud``: its x voxel indices (edge ``voxel``), non-decreasing when the
    cloud is voxel means in key order (as :func:`voxel_means` and the accumulator give them; else the points are
    sorted by x first, and that order is given back too)."""
    xi = np.floor(cloud[:, 0] / voxel)
    if np.all(xi[1:] >= xi[:-1]):
        return None, xi, voxel
    order = np.argsort(cloud[:, 0], kind="stable")
    return order, cloud[order, 0], 0.0


def _in_box(cloud: np.ndarray, lo: np.ndarray, hi: np.ndarray, by_x: tuple | None) -> np.ndarray:
    """Indices, ascending, of the points strictly inside the x-y box (lo, hi); with ``by_x`` (:func:`_x_order`)
    only the points in a slice around its x range are tested."""
    if by_x is None:
        return np.flatnonzero(np.all((cloud[:, :2] > lo) & (cloud[:, :2] < hi), axis=1))
    order, xs, voxel = by_x
    if order is None:  # voxel order: the voxels of x in (lo, hi) are a slice
        a, b = (
            np.searchsorted(xs, np.floor(lo[0] / voxel), side="left"),
            np.searchsorted(xs, np.floor(hi[0] / voxel), side="right"),
        )
        sl = cloud[a:b]
        inside = (sl[:, 0] > lo[0]) & (sl[:, 0] < hi[0]) & (sl[:, 1] > lo[1]) & (sl[:, 1] < hi[1])
        return a + np.flatnonzero(inside)
    cand = order[np.searchsorted(xs, lo[0], side="right") : np.searchsorted(xs, hi[0], side="left")]
    y = cloud[cand, 1]
    return np.sort(cand[(y > lo[1]) & (y < hi[1])])


def _measure_plane(
    cluster: np.ndarray,
    depth_c: np.ndarray,
    n: np.ndarray,
    d: float,
    u_axis: np.ndarray,
    cloud: np.ndarray,
    views: np.ndarray | None,
    p: TunnelDetectorParams,
    by_x: tuple | None = None,
) -> FrameDetection | None:
    b = p.bar
    if len(cluster) < 2 * p.min_bar_points:
        return None
    lo, hi = _percentiles(depth_c, (10, 90))
    if hi - lo > p.max_thickness:
        return None
    u_c = cluster @ u_axis
    u_lo, u_hi = _percentiles(u_c, (1, 99))
    if not p.min_opening + 2 * b - 0.05 <= u_hi - u_lo <= p.max_opening + 2 * b + 0.05:
        return None
    # the frame's points: a slab around the plane, within the cluster's horizontal span (the bounding box first)
    reach = 2 * b + p.slab + p.cluster_voxel
    near = _in_box(cloud, cluster[:, :2].min(axis=0) - reach, cluster[:, :2].max(axis=0) + reach, by_x)
    cloud = cloud[near]
    if views is not None:
        views = views[near]
    depth = cloud @ n - d
    u_all = cloud @ u_axis
    z_all = cloud[:, 2]
    in_slab = (
        (np.abs(depth) < p.slab)
        & (u_all > u_lo - 2 * b)
        & (u_all < u_hi + 2 * b)
        & (z_all < cluster[:, 2].max() + 2 * b)
    )
    v_hi = _percentiles(cluster[:, 2], (99,))[0]
    # Returns of rays grazing the plane carry their range noise into it: the bars are read on the points met
    # most squarely that suffice (3x the minimum on every bar), else on all above min_incidence.
    incidence = np.ones(len(cloud)) if views is None else np.abs(views @ n)
    base = in_slab & (incidence >= p.min_incidence)
    bars = None
    for level, need in ((0.9, 3 * p.min_bar_points), (0.75, 3 * p.min_bar_points), (p.min_incidence, p.min_bar_points)):
        if level < p.min_incidence:
            continue
        sel = in_slab & (incidence >= level)
        bars = _read_bars(u_all[sel], z_all[sel], u_lo, u_hi, v_hi, p, need)
        if bars is not None:
            in_slab = sel
            break
    if bars is None:
        return None
    pts, u, v, d_pts = cloud[in_slab], u_all[in_slab], z_all[in_slab], depth[in_slab]
    u_left, u_right, v_top, v_bot, top_pts, bot_pts, left, right = bars
    width, height = u_right - u_left - b, v_top - v_bot - b
    if not (p.min_opening <= width <= p.max_opening and p.min_opening <= height <= p.max_opening):
        return None
    own = top_pts | bot_pts | left | right
    margin = max(2 * p.voxel, 0.02)
    hole = (
        (u > u_left + b / 2 + margin)
        & (u < u_right - b / 2 - margin)
        & (v > v_bot + b / 2 + margin)
        & (v < v_top - b / 2 - margin)
    )
    if hole.sum() > p.max_hole_fraction * own.sum():
        return None
    frame_pts = own & (v > v_bot - b) & (u > u_left - b) & (u < u_right + b)  # the bars, no floor, no legs
    support = int(
        np.count_nonzero(
            base & (z_all > v_bot - b) & (z_all < v_top + b) & (u_all > u_left - b) & (u_all < u_right + b)
        )
    )
    u0, v0 = 0.5 * (u_left + u_right), 0.5 * (v_top + v_bot)
    # depth: a point is on the face its ray met, half a bar before the frame's middle plane
    shift = 0.0 if views is None else np.sign(views[in_slab][own] @ n) * (b / 2)
    d0 = d + float(np.median(d_pts[own] + shift))
    centre = d0 * n + u0 * u_axis + np.array([0.0, 0.0, v0])
    return FrameDetection(
        centre_W=centre,
        normal_W=n,
        width=float(width),
        height=float(height),
        support=support,
        points_W=pts[frame_pts],
        cluster_mean_W=pts[frame_pts].mean(axis=0),
    )


def order_along_course(detections: list[FrameDetection], origin_W: object = None) -> list[FrameDetection]:
    """Detections in flying order (from the one nearest ``origin_W``, each next the nearest remaining; by x
    without an origin), each normal pointing along the course (towards the next frame; the last one away from
    the previous, a lone one away from the origin or along +x)."""
    if not detections:
        return []
    centres = np.array([f.centre_W for f in detections])
    if origin_W is None:
        order = list(np.lexsort((centres[:, 1], centres[:, 0])))
    else:
        here, left, order = (
            _points("origin_W", np.reshape(np.asarray(origin_W, dtype=float), (1, 3)))[0],
            list(range(len(detections))),
            [],
        )
        while left:
            k = min(left, key=lambda i: (float(np.linalg.norm(centres[i] - here)), i))
            order.append(k)
            left.remove(k)
            here = centres[k]
    out = [detections[k] for k in order]
    result = []
    for k, f in enumerate(out):
        if k + 1 < len(out):
            along = out[k + 1].centre_W - f.centre_W
        elif k > 0:
            along = f.centre_W - out[k - 1].centre_W
        elif origin_W is not None:
            along = f.centre_W - np.reshape(np.asarray(origin_W, dtype=float), 3)
        else:
            along = np.array([1.0, 0.0, 0.0])
        n = f.normal_W if float(f.normal_W @ along) >= 0 else -f.normal_W
        result.append(FrameDetection(f.centre_W, n, f.width, f.height, f.support, f.points_W, f.cluster_mean_W))
    return result


def _views(sensor_W: object, pts: np.ndarray) -> np.ndarray | None:
    """Unit directions (N, 3) from the sensor to each point, or None without a sensor position."""
    if sensor_W is None:
        return None
    s = np.asarray(sensor_W, dtype=float) if not isinstance(sensor_W, (str, bytes)) else np.zeros(0)
    if s.shape != (3,) and s.shape != pts.shape:
        raise ValueError(f"sensor_W must have shape (3,) or {pts.shape} [m], got {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("sensor_W must be finite")
    d = pts - s
    return d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)


def detect_frames(
    points_W: object,
    params: TunnelDetectorParams | None = None,
    expected: int | None = None,
    origin_W: object = None,
    sensor_W: object = None,
) -> list[FrameDetection]:
    """The tunnel frames in ``points_W`` (N, 3) [m], in flying order from ``origin_W`` (see
    :func:`order_along_course`). ``expected``: keep at most this many frames (the best supported).
    ``sensor_W``: where the LiDAR was, (3,) for all points or (N, 3) one per point [m]. With it a frame's depth along its normal is the middle
    of its bars (the side a ray met is known); without, the median of its points (biased by up to half a bar
    towards the sensor).
    Deterministic: the same points and params give the same detections."""
    p = TunnelDetectorParams() if params is None else params
    if not isinstance(p, TunnelDetectorParams):
        raise TypeError(f"params must be a TunnelDetectorParams, got {type(params).__name__}")
    if expected is not None and (
        isinstance(expected, bool) or not isinstance(expected, numbers.Integral) or expected < 1
    ):
        raise ValueError(f"expected must be None or an integer >= 1 (frames), got {expected!r}")
    pts = _points("points_W", points_W)
    keep = (pts[:, 2] <= p.ceiling_z) & (pts[:, 2] >= p.floor_z + p.floor_band)
    if p.roi_min_W is not None:
        keep &= np.all(pts >= np.asarray(p.roi_min_W), axis=1)
    if p.roi_max_W is not None:
        keep &= np.all(pts <= np.asarray(p.roi_max_W), axis=1)
    views = _views(sensor_W, pts)
    if views is None:
        return detect_in_voxels(voxel_means(pts[keep], p.voxel), None, p, expected, origin_W)
    cloud, views = voxel_means(pts[keep], p.voxel, views[keep])
    return detect_in_voxels(cloud, views, p, expected, origin_W)


COLUMN_CELL = 0.1
"""Edge of the x-y columns of :func:`column_keys` [m]."""


def column_keys(points: np.ndarray, cell: float = COLUMN_CELL) -> np.ndarray:
    """One int64 key per point naming its x-y column of edge ``cell`` [m]."""
    ij = np.floor(points[:, :2] / cell).astype(np.int64) + (1 << 30)
    return (ij[:, 0] << 31) | ij[:, 1]


def _in_tall_columns(points: np.ndarray, top: float) -> np.ndarray:
    """Mask of the points in x-y columns that hold a point above ``top`` [m] (walls, poles)."""
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    keys = column_keys(points)
    return np.isin(keys, np.unique(keys[points[:, 2] > top]))


def _overlap(a: FrameDetection, b: FrameDetection, p: TunnelDetectorParams) -> bool:
    """``a`` and ``b`` cannot both be frames: too close, or ``a``'s centre in ``b``'s outline, near its plane."""
    d = a.centre_W - b.centre_W
    if np.linalg.norm(d) < p.min_separation:
        return True
    u = np.array([-b.normal_W[1], b.normal_W[0], 0.0])
    return (
        abs(d @ b.normal_W) < p.min_separation and abs(d @ u) < b.width / 2 + p.bar and abs(d[2]) < b.height / 2 + p.bar
    )


def detect_in_voxels(
    cloud_W: np.ndarray,
    views_W: np.ndarray | None,
    params: TunnelDetectorParams,
    expected: int | None = None,
    origin_W: object = None,
) -> list[FrameDetection]:
    """:func:`detect_frames` on points already cropped and reduced to voxel means ``cloud_W`` (M, 3) [m], with
    the mean unit ray direction of each voxel ``views_W`` (M, 3) or None (the detector's accumulated map)."""
    p = params
    coarse = voxel_means(cloud_W[cloud_W[:, 2] > p.floor_z + p.floor_cut], p.cluster_voxel)
    coarse = coarse[~_in_tall_columns(coarse, p.max_frame_top)]
    labels = _dbscan(coarse, p.eps, p.min_points)
    by_x = _x_order(cloud_W, p.voxel)
    found: list[FrameDetection] = []
    # clusters in the order of their first voxel (coarse is sorted by voxel), each with its own RANSAC draws:
    # however the clustering numbers them, the same cloud gives the same detections
    labelled, first = np.unique(labels[labels >= 0], return_index=True)
    for label in labelled[np.argsort(first)]:
        cluster = coarse[labels == label]
        if len(cluster) < 2 * p.min_bar_points:
            continue
        # no line through a cluster spans more than its x-y diagonal: one narrower than the smallest frame
        # (min_opening plus two bars, less the 5 cm _measure_plane allows) holds none
        if float(np.hypot(*np.ptp(cluster[:, :2], axis=0))) < p.min_opening + 2 * p.bar - 0.05 - 1e-9:
            continue
        rng = np.random.default_rng([p.seed, len(cluster)])
        for _ in range(3):  # frames close together may share a cluster: each plane in turn
            det, on_plane = _measure(cluster, cloud_W, views_W, p, rng, by_x)
            if det is not None:
                found.append(det)
            if on_plane is None:
                break
            cluster = cluster[~on_plane]
            if len(cluster) < 4 * p.min_bar_points:
                break
    # Two frames cannot stand closer than min_separation, nor one's centre within another's outline and less
    # than min_separation before or behind it: of such a pair (one frame seen twice, a noisy fringe beside it
    # taken for a frame) the one with more support stays.
    kept: list[int] = []
    for k in sorted(range(len(found)), key=lambda k: (-found[k].support, k)):
        if not any(_overlap(found[k], found[j], p) for j in kept):
            kept.append(k)
    found = [found[k] for k in sorted(kept)]
    if expected is not None and len(found) > expected:
        best = sorted(range(len(found)), key=lambda k: (-found[k].support, k))[:expected]
        found = [found[k] for k in sorted(best)]
    return order_along_course(found, origin_W)

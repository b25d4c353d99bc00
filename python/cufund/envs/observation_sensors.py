"""Ray-cast observations for every env of a batch in one C++ call: a pinhole depth image or LiDAR ranges.

Each vehicle carries one sensor, mounted at (``p_BS``, ``q_BS``) on its body (FLU; the sensor looks along its
own +x, like the body). :meth:`BatchRangeSensor.observe` takes the N body poses and returns (N, H, W) depths or
(N, R) ranges, cast with Embree by :func:`cufund._core.lidar.batch_cast` (GIL released, threads over vehicles,
each vehicle's rays in the 8-wide coherent packets of ``RaycastScene.cast_rays(coherent=True)``: bit for bit
its hits). Optionally the vehicles' boxes are in the cast, so that each sensor sees the others (not itself).
A depth camera in a world of vertical convex prisms and horizontal rectangles only (the forest: capped n-gon
trunks on a ground quad; :func:`prism_scene` recognises it) is cast by the exact analytic caster
:func:`cufund._core.envs.prism_depth_cast` instead (cpp/envs/prism_cast.h: the same depths within float rounding,
several times faster); any other world, a LiDAR, or vehicle boxes use Embree.

- Depth: the distance along the optical axis (+x of the sensor) of the first surface through each pixel's centre,
  rows top to bottom and columns left to right as an image (pixel (v, u) looks along (1, -x_n, -y_n) with
  x_n = (u + 0.5 - W/2) / f, y_n = (v + 0.5 - H/2) / f, f = (W/2) / tan(fov/2)).
- LiDAR: the range along each ray of frame ``frame`` of an existing scan pattern (Mid-360, VLP-16, OS1-64, Avia;
  :mod:`cufund.sensors.patterns`), every ray cast at the frame's pose (no motion distortion within a frame).

A return outside [range_min, range_max] or a miss reads ``range_max`` (a bounded observation). The noise is
the LiDAR's range model (:class:`cufund.sensors.LidarParams`: ``range_noise_std``, ``range_noise_per_m``,
``dropout``; a dropped return reads range_max), off by default and seeded: vehicle i's draws in frame k come
from a stream keyed by (seed + i, k): vehicle i of a batch seeded s draws what a batch of one seeded s + i does.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cufund import _core
from cufund.core.config import ConfigError, from_dict
from cufund.geometry import quat_conjugate, quat_mul
from cufund.sensors import patterns
from cufund.sensors.lidar import LidarParams

__all__ = [
    "BatchRangeSensor",
    "DepthCameraSpec",
    "LidarSpec",
    "SensorSpec",
    "VehicleBoxes",
    "prism_scene",
    "sensor_poses",
]

_PATTERNS: dict[str, Callable[[], patterns.ScanPattern]] = {
    "mid360": patterns.mid360,
    "vlp16": patterns.vlp16,
    "os1_64": patterns.os1_64,
    "avia": patterns.avia,
}


def _number(where: str, value: Any, lo: float = 0.0, hi: float = math.inf, allow_inf: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(f"{where} must be a number, got {value!r}")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf) or not lo <= v <= hi:
        raise ConfigError(f"{where} must be a number in [{lo:g}, {hi:g}], got {value!r}")
    return v


def _whole(where: str, value: Any, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= int(value) <= hi:
        raise ConfigError(f"{where} must be a whole number in [{lo}, {hi}], got {value!r}")
    return int(value)


def _mount(where: str, p: Any, q: Any) -> tuple[tuple[float, ...], tuple[float, ...]]:
    pa = np.asarray(p, dtype=float).reshape(-1)
    qa = np.asarray(q, dtype=float).reshape(-1)
    if pa.shape != (3,) or not np.all(np.isfinite(pa)):
        raise ConfigError(f"{where}.p_BS must be 3 finite numbers [m], got {p!r}")
    if qa.shape != (4,) or not np.all(np.isfinite(qa)) or not np.linalg.norm(qa) > 0:
        raise ConfigError(f"{where}.q_BS must be a non-zero quaternion [w, x, y, z], got {q!r}")
    return tuple(pa.tolist()), tuple((qa / np.linalg.norm(qa)).tolist())


@dataclasses.dataclass(frozen=True)
class _RangeTerms:
    range_min: float = 0.05
    """Returns closer than this read range_max [m]."""
    range_max: float = 20.0
    """Returns farther than this, and misses, read range_max [m]."""
    range_noise_std: float = 0.0
    """Gaussian range noise sigma(r) = range_noise_std + range_noise_per_m r [m] (as cufund.sensors.LidarParams)."""
    range_noise_per_m: float = 0.0
    """[m/m]"""
    dropout: float = 0.0
    """Probability that a valid return is lost (reads range_max), in [0, 1)."""
    p_BS: tuple[float, ...] = (0.0, 0.0, 0.0)
    """The sensor's position on the body [m] (FLU)."""
    q_BS: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0)
    """The sensor's attitude on the body [w, x, y, z]: identity looks along the body's +x."""

    def _check_range(self, where: str) -> None:
        rmin = _number(f"{where}.range_min", self.range_min)
        rmax = _number(f"{where}.range_max", self.range_max, rmin)
        if rmax <= 0:
            raise ConfigError(f"{where}.range_max must be > 0 [m], got {self.range_max!r}")
        object.__setattr__(self, "range_min", rmin)
        object.__setattr__(self, "range_max", rmax)
        for name in ("range_noise_std", "range_noise_per_m"):
            object.__setattr__(self, name, _number(f"{where}.{name}", getattr(self, name)))
        object.__setattr__(self, "dropout", _number(f"{where}.dropout", self.dropout, 0.0, 0.999999))
        p, q = _mount(where, self.p_BS, self.q_BS)
        object.__setattr__(self, "p_BS", p)
        object.__setattr__(self, "q_BS", q)


@dataclasses.dataclass(frozen=True)
class DepthCameraSpec(_RangeTerms):
    """A pinhole depth camera of ``width`` x ``height`` pixels and horizontal field of view ``fov_deg`` (square
    pixels)."""

    width: int = 64
    height: int = 64
    fov_deg: float = 90.0
    """Horizontal field of view [deg], in (0, 170]."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "width", _whole("depth.width", self.width, 1, 4096))
        object.__setattr__(self, "height", _whole("depth.height", self.height, 1, 4096))
        object.__setattr__(self, "fov_deg", _number("depth.fov_deg", self.fov_deg, 1e-3, 170.0))
        self._check_range("depth")

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) of one image."""
        return (self.height, self.width)

    @property
    def focal_px(self) -> float:
        """Focal length [px]."""
        return (self.width / 2.0) / math.tan(math.radians(self.fov_deg) / 2.0)

    def directions(self) -> np.ndarray:
        """(H W, 3) float32 sensor-frame directions (1, -x_n, -y_n), row-major over the image: the distance along
        each is the depth along the optical axis."""
        f = self.focal_px
        xn = (np.arange(self.width) + 0.5 - self.width / 2.0) / f
        yn = (np.arange(self.height) + 0.5 - self.height / 2.0) / f
        xx, yy = np.meshgrid(xn, yn)
        return np.stack([np.ones_like(xx), -xx, -yy], -1).reshape(-1, 3).astype(np.float32)


@dataclasses.dataclass(frozen=True)
class LidarSpec(_RangeTerms):
    """A LiDAR of one of cufund's scan patterns; every ``stride``-th ray of frame ``frame`` (the same rays every
    step: an observation of fixed size)."""

    pattern: str = "mid360"
    """mid360, vlp16, os1_64 or avia (cufund.sensors.patterns)."""
    frame: int = 0
    stride: int = 20
    """Keep every stride-th ray of the frame (the Mid-360's 20 000 rays at stride 20: 1000)."""
    range_max: float = 40.0

    def __post_init__(self) -> None:
        if self.pattern not in _PATTERNS:
            raise ConfigError(f"lidar.pattern must be one of {', '.join(_PATTERNS)}, got {self.pattern!r}")
        object.__setattr__(self, "frame", _whole("lidar.frame", self.frame, 0, 2**40))
        object.__setattr__(self, "stride", _whole("lidar.stride", self.stride, 1, 1_000_000))
        self._check_range("lidar")

    @classmethod
    def from_lidar_params(cls, params: LidarParams, **fields: Any) -> LidarSpec:
        """The range model of a :class:`cufund.sensors.LidarParams` (``range_min``, ``range_max``,
        ``range_noise_std``, ``range_noise_per_m``, ``dropout``; its other realism terms are not modelled here), with
        this spec's other ``fields`` (pattern, stride, mount, ...)."""
        names = ("range_min", "range_max", "range_noise_std", "range_noise_per_m", "dropout")
        return cls(**{n: getattr(params, n) for n in names}, **fields)

    def directions(self) -> np.ndarray:
        """(R, 3) float32 unit directions in the sensor frame."""
        d = np.asarray(_PATTERNS[self.pattern]().frame(self.frame).directions(), dtype=np.float64)[:: self.stride]
        return (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)

    @property
    def shape(self) -> tuple[int]:
        """(R,) rays per observation."""
        return (len(self.directions()),)


SensorSpec = DepthCameraSpec | LidarSpec


def sensor_spec(kind: str, **kwargs: Any) -> SensorSpec:
    """``depth`` or ``lidar`` with its fields."""
    if kind == "depth":
        return from_dict(DepthCameraSpec, kwargs, kind)
    if kind == "lidar":
        return from_dict(LidarSpec, kwargs, kind)
    raise ConfigError(f"sensor must be 'depth' or 'lidar', got {kind!r}")


@dataclasses.dataclass(frozen=True)
class VehicleBoxes:
    """The vehicles' boxes in a cast: each vehicle an oriented box of ``half_extents`` [m] (body axes) centred on
    its body origin; sensor i does not see its own."""

    half_extents: tuple[float, float, float] = (0.1, 0.1, 0.03)

    def __post_init__(self) -> None:
        h = np.asarray(self.half_extents, dtype=float).reshape(-1)
        if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h < 0):
            raise ConfigError(f"half_extents must be 3 finite numbers >= 0 [m], got {self.half_extents!r}")
        object.__setattr__(self, "half_extents", tuple(h.tolist()))


def sensor_poses(
    p_WB: np.ndarray, q_WB: np.ndarray, p_BS: tuple[float, ...], q_BS: tuple[float, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """(p_WS (N, 3), q_WS (N, 4)) of a sensor mounted at (p_BS, q_BS) on bodies at (p_WB, q_WB [w, x, y, z])."""
    p = np.asarray(p_WB, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(q_WB, dtype=np.float64).reshape(-1, 4)
    if not any(p_BS) and tuple(q_BS) == (1.0, 0.0, 0.0, 0.0):
        return p, q
    qs = np.broadcast_to(np.asarray(q_BS), q.shape)
    pb = np.zeros_like(q)
    pb[:, 1:] = p_BS
    # R_WB p_BS = vec(q pb q*)
    rotated = quat_mul(quat_mul(q, pb), quat_conjugate(q))[:, 1:]
    return p + rotated, quat_mul(q, qs)


def _hull(xy: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2-D points (Andrew's monotone chain; collinear points dropped)."""
    pts = sorted(set(map(tuple, xy.tolist())))
    if len(pts) < 3:
        return np.asarray(pts)

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.asarray(lower[:-1] + upper[:-1])


def _prism(v: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, tuple[float, ...]] | None:
    """(planes (K, 3) (nx, ny, c), (zmin, zmax, x0, x1, y0, y1)) when the mesh is the surface of a vertical convex
    prism (every vertex on its bottom or top cap, every triangle on one of its faces, their areas summing to its
    surface), else None."""
    z = v[:, 2]
    z0, z1 = float(z.min()), float(z.max())
    if not z1 > z0 or not np.all((z == z0) | (z == z1)):
        return None
    hull = _hull(v[:, :2])
    if len(hull) < 3:
        return None
    e = np.roll(hull, -1, axis=0) - hull
    length = np.hypot(e[:, 0], e[:, 1])
    # Outward for a counter-clockwise hull; rounded to float32 as the caster stores them, c from the rounded normal.
    n = (np.stack([e[:, 1], -e[:, 0]], 1) / length[:, None]).astype(np.float32).astype(np.float64)
    c = np.einsum("ij,ij->i", n, hull)
    scale = max(1.0, float(np.abs(v).max()))
    tol = 1e-6 * scale
    if np.any(v[:, :2] @ n.T - c > tol):
        return None
    a, b, d = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    on_cap = ((a[:, 2] == b[:, 2]) & (b[:, 2] == d[:, 2])).astype(bool)
    dist = np.abs(np.stack([a[:, :2] @ n.T - c, b[:, :2] @ n.T - c, d[:, :2] @ n.T - c]))  # (3, T, K)
    on_side = np.any(np.all(dist <= tol, axis=0), axis=1)
    if not np.all(on_cap | on_side):
        return None
    area = 0.5 * np.linalg.norm(np.cross(b - a, d - a), axis=1).sum()
    poly = 0.5 * float(np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1]))
    if abs(area - (2.0 * poly + length.sum() * (z1 - z0))) > 1e-6 * max(1.0, area):
        return None
    lo, hi = v.min(0), v.max(0)
    return np.column_stack([n, c]), (z0, z1, float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))


def _rect(v: np.ndarray, tri: np.ndarray) -> tuple[float, ...] | None:
    """(z, x0, x1, y0, y1) when the mesh is an axis-aligned horizontal rectangle covered once, else None."""
    if not np.all(v[:, 2] == v[0, 2]):
        return None
    lo, hi = v[:, :2].min(0), v[:, :2].max(0)
    if not np.all(np.isin(v[:, 0], (lo[0], hi[0])) & np.isin(v[:, 1], (lo[1], hi[1]))):
        return None
    a, b, d = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    ab, ad = b[:, :2] - a[:, :2], d[:, :2] - a[:, :2]
    area = 0.5 * np.abs(ab[:, 0] * ad[:, 1] - ab[:, 1] * ad[:, 0]).sum()
    if abs(area - float(np.prod(hi - lo))) > 1e-9 * max(1.0, area):
        return None
    return (float(v[0, 2]), float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))


def prism_scene(world: Any) -> _core.envs.PrismScene | None:
    """The world's meshes as a :class:`cufund._core.envs.PrismScene` for the analytic depth caster, or None when
    one of them is neither a vertical convex prism nor an axis-aligned horizontal rectangle (then Embree casts).
    The vertices are taken as Embree stores them (float32), so both cast the same surfaces."""
    planes: list[np.ndarray] = []
    begin = [0]
    prisms: list[tuple[float, ...]] = []
    rects: list[tuple[float, ...]] = []
    for o in world.objects:
        v = np.asarray(o.vertices, dtype=np.float32).astype(np.float64)
        tri = np.asarray(o.triangles, dtype=np.int64)
        if len(tri) == 0:
            continue
        rect = _rect(v, tri)
        if rect is not None:
            rects.append(rect)
            continue
        prism = _prism(v, tri)
        if prism is None:
            return None
        planes.append(prism[0])
        begin.append(begin[-1] + len(prism[0]))
        prisms.append(prism[1])
    return _core.envs.PrismScene(
        np.concatenate(planes) if planes else np.zeros((0, 3)),
        np.asarray(begin, dtype=np.int64),
        np.asarray(prisms, dtype=np.float64).reshape(-1, 6),
        np.asarray(rects, dtype=np.float64).reshape(-1, 5),
    )


class BatchRangeSensor:
    """One :data:`SensorSpec` sensor on each of N vehicles in the world of ``scene`` (a
    :class:`cufund._core.lidar.RaycastScene`, e.g. ``World.raycast_scene``). With ``prisms`` (:func:`prism_scene`
    of the same world), a depth camera without boxes is cast by the analytic caster."""

    def __init__(
        self,
        scene: _core.lidar.RaycastScene,
        spec: SensorSpec,
        boxes: VehicleBoxes | None = None,
        seed: int = 0,
        nthreads: int = 0,
        prisms: _core.envs.PrismScene | None = None,
    ) -> None:
        if not isinstance(spec, (DepthCameraSpec, LidarSpec)):
            raise ConfigError(f"spec must be a DepthCameraSpec or a LidarSpec, got {type(spec).__name__}")
        self.scene = scene
        self.spec = spec
        self.boxes = boxes
        self.seed = _whole("seed", seed, 0, 2**63 - 1)
        self.nthreads = _whole("nthreads", nthreads, 0, 1 << 20)
        self.d_S = spec.directions()
        self.shape = spec.shape
        self.prisms = prisms if isinstance(spec, DepthCameraSpec) and boxes is None else None

    def observe(
        self, p_WB: np.ndarray, q_WB: np.ndarray, frame: int = 0, present: np.ndarray | None = None
    ) -> np.ndarray:
        """(N, *shape) float32 of the vehicles at (p_WB (N, 3) [m], q_WB (N, 4) [w, x, y, z]); ``frame`` keys the
        noise draws. With boxes, ``present`` (N,) bool leaves the boxes of the vehicles where it is False out of
        the cast (vehicles no longer in the world)."""
        s = self.spec
        p_WB = np.asarray(p_WB, dtype=np.float64).reshape(-1, 3)
        q_WB = np.asarray(q_WB, dtype=np.float64).reshape(-1, 4)
        p_WS, q_WS = sensor_poses(p_WB, q_WB, s.p_BS, s.q_BS)
        # the range model and the noise streams, the same for both casters
        model: dict[str, Any] = {
            "range_min": s.range_min,
            "range_max": s.range_max,
            "miss_value": s.range_max,
            "noise_std": s.range_noise_std,
            "noise_per_m": s.range_noise_per_m,
            "dropout": s.dropout,
            "seed": self.seed,
            "frame": int(frame),
            "nthreads": self.nthreads,
        }
        if self.prisms is not None:
            assert isinstance(s, DepthCameraSpec)
            depth = _core.envs.prism_depth_cast(
                self.prisms, self.d_S, p_WS, q_WS, width=s.width, height=s.height, focal=s.focal_px, **model
            )
            return depth.reshape((len(p_WB), *self.shape))
        box: dict[str, Any] = {}
        if self.boxes is not None:
            n = len(p_WB)
            keep = np.ones(n, dtype=bool) if present is None else np.asarray(present, dtype=bool).reshape(n)
            owner = np.full(n, -1, dtype=np.int64)
            owner[keep] = np.arange(int(keep.sum()))
            box = {
                "box_p_W": p_WB[keep],
                "box_q_W": q_WB[keep],
                "box_half_extents": np.broadcast_to(np.asarray(self.boxes.half_extents), (int(keep.sum()), 3)),
                "box_owner": owner,
            }
        out = _core.lidar.batch_cast(self.scene, self.d_S, p_WS, q_WS, **model, **box)
        return out.reshape((len(p_WB), *self.shape))

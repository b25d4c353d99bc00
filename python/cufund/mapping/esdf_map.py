"""Occupancy grid from LiDAR scans with an exact, incrementally updated Euclidean signed distance field."""

from __future__ import annotations

import copy
import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from cufund import _core
from cufund.core import limits
from cufund.core.config import ConfigError, from_dict, real_number, vector3
from cufund.geometry import Transform

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class EsdfMapParams:
    """Geometry, sensor model and options of an :class:`EsdfMap`. SI units, world frame ENU.

    The sensor model is OctoMap's: each beam adds ``log_odds_miss`` to every voxel it crosses and
    ``log_odds_hit`` to the voxel holding its end (once per voxel and scan; hits win), clamped to
    ``[log_odds_min, log_odds_max]``. Unknown voxels (never observed) count as free.
    """

    resolution: float
    """Voxel edge length [m], > 0 (typically 0.05 to 0.2)."""
    size: tuple[float, float, float]
    """Extent of the mapped box along x, y, z [m]; rounded up to whole voxels."""
    origin_W: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """World position of the box's minimum corner [m]."""
    log_odds_hit: float = 0.85
    """Log-odds added at a beam end (> 0; 0.85 is p = 0.7)."""
    log_odds_miss: float = -0.4
    """Log-odds added along a beam (< 0; -0.4 is p = 0.4)."""
    log_odds_min: float = -2.0
    """Lower clamping bound of the log-odds."""
    log_odds_max: float = 3.5
    """Upper clamping bound of the log-odds."""
    log_odds_occupied: float = 0.0
    """A voxel is occupied when its log-odds exceeds this; in [log_odds_min, log_odds_max)."""
    max_range: float = math.inf
    """Beams longer than this are cut here [m] and mark only free space; > 0."""
    signed: bool = True
    """Keep the distance inside obstacles too, so the field is negative there."""
    nthreads: int = 0
    """Worker threads for the distance field and queries; 0 uses every core."""
    merge_beams: bool = False
    """Cast one beam per distinct end voxel and scan (the scan's first point ending there; a beam cut at the
    map's border or at ``max_range`` ends in the last voxel it reaches inside) instead of one per point. Hits
    are unchanged; the free space marked is the part of the per-point free space the kept beams cross, so
    every log-odds is >= the per-point update's and the occupied voxels are a superset of its. Much cheaper
    when many points share an end voxel (a LiDAR's dense scan on a 10 cm grid)."""

    def __post_init__(self) -> None:
        res = real_number("resolution", self.resolution)
        if not (math.isfinite(res) and float(res) > 0):
            raise ConfigError(f"resolution must be finite and > 0 [m], got {self.resolution!r}")
        size = vector3("size", self.size, " [m]", finite=True)
        if min(size) <= 0:
            raise ConfigError(f"size must be > 0 [m] on every axis, got {size}")
        for axis, extent in zip("xyz", size, strict=True):
            if not extent / res < 2**31:  # also catches a subnormal resolution (extent / res = inf)
                raise ConfigError(
                    f"size / resolution must give fewer than 2^31 voxels per axis, got {extent} / {res} along {axis}"
                )
        object.__setattr__(self, "resolution", res)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "origin_W", vector3("origin_W", self.origin_W, " [m]", finite=True))
        for name in ("log_odds_hit", "log_odds_miss", "log_odds_min", "log_odds_max", "log_odds_occupied", "max_range"):
            object.__setattr__(self, name, real_number(name, getattr(self, name)))
        if not (math.isfinite(self.log_odds_hit) and self.log_odds_hit > 0):
            raise ConfigError(f"log_odds_hit must be finite and > 0, got {self.log_odds_hit}")
        if not (math.isfinite(self.log_odds_miss) and self.log_odds_miss < 0):
            raise ConfigError(f"log_odds_miss must be finite and < 0, got {self.log_odds_miss}")
        if not (self.log_odds_min <= self.log_odds_occupied < self.log_odds_max):
            raise ConfigError(
                "log-odds bounds must satisfy log_odds_min <= log_odds_occupied < log_odds_max, got "
                f"{self.log_odds_min}, {self.log_odds_occupied}, {self.log_odds_max}"
            )
        if not self.max_range > 0:
            raise ConfigError(f"max_range must be > 0 [m], got {self.max_range}")
        for name in ("signed", "merge_beams"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ConfigError(f"{name} must be a bool, got {getattr(self, name)!r}")
        if isinstance(self.nthreads, bool) or not isinstance(self.nthreads, numbers.Integral) or self.nthreads < 0:
            raise ConfigError(f"nthreads must be an integer >= 0 (0 = all cores), got {self.nthreads!r}")

    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxels along x, y, z."""
        return tuple(max(1, math.ceil(s / self.resolution - 1e-9)) for s in self.size)  # type: ignore[return-value]

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EsdfMapParams:
        """From a plain mapping (e.g. parsed YAML); unknown keys raise :class:`ConfigError`."""
        return from_dict(cls, data)


@dataclass(frozen=True)
class ScanStats:
    """What one update did."""

    points: int
    """Points given."""
    nan_points: int
    """Points skipped because a coordinate was NaN or infinite."""
    outside: int
    """Beams whose end lies outside the map: free space marked up to the border, no hit."""
    beyond_range: int
    """Beams longer than ``max_range``: cut there, no hit."""
    beams: int
    """Beams cast: the finite points, or with ``merge_beams`` one per distinct end voxel (none that misses the map)."""
    hit_voxels: int
    """Distinct voxels updated as hit."""
    free_voxels: int
    """Distinct voxels updated as free."""
    flipped_voxels: int
    """Voxels whose occupied state changed."""
    changed_distances: int
    """Voxels whose distance changed (both the outside and the inside field)."""
    lines_recomputed: int
    """Grid lines the incremental update recomputed (a full recompute does nx*ny + nx*nz + ny*nz per field)."""
    raycast_seconds: float = field(default=0.0, compare=False)
    """Wall time [s] of the occupancy update (beam traversal and log-odds); 0 for ``set_occupied``."""
    field_seconds: float = field(default=0.0, compare=False)
    """Wall time [s] of the incremental distance-field update. Timings are not compared by ``==``."""


def _points(name: str, p: npt.ArrayLike) -> tuple[np.ndarray, bool]:
    a = np.asarray(p)
    single = a.ndim == 1 and a.shape == (3,)
    if single:
        a = a.reshape(1, 3)
    if a.ndim == 2 and a.shape[1] == 3 and a.dtype.kind in "fiu":
        bad = ~np.isfinite(a).all(axis=1)
        if bad.any():
            raise ValueError(f"{name} must be finite [m], got {a[bad][0].tolist()} in row {int(np.argmax(bad))}")
    return a, single


class EsdfMap:
    """Voxel occupancy map with an exact Euclidean signed distance field, updated after each scan.

    Voxel ``(i, j, k)`` covers ``origin_W + resolution * [i, j, k]`` to ``... + resolution``; distances
    are between voxel centres and are exactly what :func:`cufund.mapping.edt` gives for the current
    occupancy (the incremental update recomputes only the grid lines whose input changed). Queries
    interpolate the voxel-centre distances trilinearly.
    """

    def __init__(self, params: EsdfMapParams) -> None:
        if not isinstance(params, EsdfMapParams):
            raise ValueError(f"params must be an EsdfMapParams, got {type(params).__name__}")
        voxels = math.prod(params.shape)
        cap = limits.current().grid_max_voxels
        if voxels > cap:
            raise ConfigError(
                f"size / resolution must give at most grid_max_voxels = {cap} voxels, got "
                f"{params.shape} = {voxels}; raise it with cufund.core.limits.configure(grid_max_voxels=...)"
            )
        self._params = params
        self._core = _core.esdf.EsdfMap(
            params.origin_W, params.shape, params.resolution, params.log_odds_hit, params.log_odds_miss,
            params.log_odds_min, params.log_odds_max, params.log_odds_occupied, params.max_range,
            bool(params.signed), int(params.nthreads), bool(params.merge_beams),
        )  # fmt: skip

    @property
    def params(self) -> EsdfMapParams:
        return self._params

    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxels along x, y, z."""
        return self._params.shape

    def insert_scan(self, points_W: npt.ArrayLike, origin_W: npt.ArrayLike) -> ScanStats:
        """Inserts a point cloud ``points_W`` (N, 3) [m, world frame] seen from sensor position
        ``origin_W`` (3,) [m], then brings the distance field up to date.

        NaN/inf points are skipped and counted; beams ending outside the map mark free space up to
        the border and are counted in ``outside``.
        """
        return ScanStats(**self._core.insert_scan(points_W, origin_W))

    def insert_scans(self, scans: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]]) -> ScanStats:
        """Inserts several scans ``(points_W, origin_W)`` in order, each exactly as :meth:`insert_scan` would
        (the occupancy is the same), then brings the distance field up to date once. The map equals the one
        :meth:`insert_scan` per scan gives, at one field update for the batch. Statistics are summed over the
        scans; ``flipped_voxels`` counts the voxels whose state differs from before the batch."""
        return ScanStats(**self._core.insert_scans(list(scans)))

    def insert_frames(
        self,
        frames: Sequence[tuple[npt.ArrayLike, npt.ArrayLike, float]],
        poses: tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike],
        T_BL: Transform,
    ) -> ScanStats:
        """Inserts LiDAR frames measured in motion, as :meth:`insert_scans` does after placing them in the world.

        Each frame is ``(points_L, t, t_origin)``: points (N, 3) [m] in the LiDAR frame, each fired at its
        own time ``t`` (N,) [s], cast from the LiDAR position at ``t_origin`` [s]. ``poses`` are body pose
        knots ``(t (K,) [s] strictly ascending, p_W (K, 3) [m], q_WB (K, 4) [w, x, y, z])``, interpolated as
        :func:`cufund.geometry.interpolate_poses` does (linear, normalised linear quaternion, clamped at
        the ends); ``T_BL`` is the LiDAR's mounting on the body. A point's world position is
        ``p_WB(t) + R_WB(t) (R_BL p_L + t_BL)``; placing, ray casting and the field update all run in C++
        with the GIL released.
        """
        if not isinstance(T_BL, Transform):
            raise TypeError(f"T_BL must be a cufund.geometry.Transform, got {type(T_BL).__name__}")
        if not isinstance(poses, tuple) or len(poses) != 3:
            raise ValueError("poses must be a tuple (t, p_W, q_WB) of pose knots")
        t, p, q = poses
        return ScanStats(**self._core.insert_frames(list(frames), t, p, q, T_BL.R, T_BL.t))

    def set_occupied(self, ijk: npt.ArrayLike, occupied: bool | npt.ArrayLike = True) -> ScanStats:
        """Forces voxels ``ijk`` (M, 3) integer indices occupied or free (log-odds to the clamping
        bound), then updates the field; for building maps from known geometry."""
        a = np.asarray(ijk)
        if a.ndim != 2 or a.shape[1] != 3 or (a.size and a.dtype.kind not in "iu"):
            raise ValueError(f"ijk must be an integer array of shape (M, 3), got {a.dtype} {a.shape}")
        a = a.astype(np.int64, copy=False)
        n = np.asarray(self.shape)
        bad = np.any((a < 0) | (a >= n), axis=1)
        if np.any(bad):
            raise ValueError(
                f"ijk row {int(np.argmax(bad))} = {a[bad][0].tolist()} is outside the map shape {self.shape}"
            )
        occ = np.broadcast_to(np.asarray(occupied, dtype=bool), (a.shape[0],))
        index = (a[:, 0] * n[1] + a[:, 1]) * n[2] + a[:, 2]
        stats = self._core.set_occupied(index, occ.astype(np.uint8))
        return ScanStats(**stats)

    def recompute(self) -> None:
        """Recomputes the whole distance field from the occupancy (the incremental path equals it)."""
        self._core.recompute()

    def distance(self, p_W: npt.ArrayLike) -> np.ndarray:
        """Signed distance [m] at points ``p_W`` (N, 3) or (3,), trilinearly interpolated; points beyond
        the outermost voxel centres take the boundary value; a NaN or infinite point raises ValueError."""
        a, single = _points("p_W", p_W)
        d = self._core.query(a, False)
        return d[0] if single else d

    def distance_and_gradient(self, p_W: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Distances (N,) [m] and the exact gradients (N, 3) of the trilinear interpolant."""
        a, single = _points("p_W", p_W)
        d, g = self._core.query(a, True)
        return (d[0], g[0]) if single else (d, g)

    def distances(self) -> np.ndarray:
        """Voxel-centre distances (nx, ny, nz) [m]: +inf everywhere while nothing is occupied."""
        return self._core.distances()

    def occupied(self) -> np.ndarray:
        """Occupied voxels as a boolean (nx, ny, nz) array."""
        return self._core.occupied()

    def log_odds(self) -> np.ndarray:
        """Log-odds of every voxel (nx, ny, nz) float32; 0 = never observed."""
        return self._core.log_odds()

    def squared_distances(self) -> tuple[np.ndarray, np.ndarray]:
        """Integer squared voxel distances (outside field, inside field), (nx, ny, nz) int32 each;
        2**31 - 1 where there is no site. The exact state the incremental update maintains."""
        return self._core.outside_squared(), self._core.inside_squared()

    def voxel_centers(self, axis: str) -> np.ndarray:
        """World coordinates [m] of the voxel centres along ``axis`` ("x", "y" or "z")."""
        a = self._axis(axis)
        p = self._params
        return p.origin_W[a] + p.resolution * (np.arange(self.shape[a]) + 0.5)

    def slice(self, axis: str, position: float) -> np.ndarray:
        """2-D distances [m] of the voxel layer normal to ``axis`` holding world coordinate
        ``position`` [m] (clamped to the map); rows/columns follow the other two axes in x, y, z order."""
        a = self._axis(axis)
        p = self._params
        pos = real_number("position", position)
        if not math.isfinite(pos):
            raise ValueError(f"position must be finite [m], got {position!r}")
        i = int(np.clip(math.floor((pos - p.origin_W[a]) / p.resolution), 0, self.shape[a] - 1))
        return np.take(self.distances(), i, axis=a)

    def occupied_points(self) -> np.ndarray:
        """Centres (M, 3) [m, world] of the occupied voxels, e.g. for a MeshCat point cloud."""
        ijk = np.argwhere(self.occupied())
        return np.asarray(self._params.origin_W) + self._params.resolution * (ijk + 0.5)

    def copy(self) -> EsdfMap:
        """A deep copy (occupancy and field)."""
        return copy.deepcopy(self)

    def __getstate__(self) -> dict[str, Any]:
        # The log-odds are the whole state: the field is a function of the occupancy (the incremental
        # update equals a full recompute bit for bit), rebuilt on unpickling.
        return {"params": self._params, "log_odds": self.log_odds()}

    def __setstate__(self, state: dict[str, Any]) -> None:
        EsdfMap.__init__(self, state["params"])
        self._core.set_log_odds(state["log_odds"])

    def __deepcopy__(self, memo: dict[int, Any]) -> EsdfMap:
        new = EsdfMap.__new__(EsdfMap)
        new._params = self._params
        new._core = _core.esdf.EsdfMap(self._core)
        return new

    @staticmethod
    def _axis(axis: str) -> int:
        if axis not in _AXES:
            raise ValueError(f'axis must be "x", "y" or "z", got {axis!r}')
        return _AXES[axis]

"""Certified clearance on an ESDF map: the scalar query and motion check path planners call per state.

``clearance(p)`` is a lower bound on the distance [m] from ``p`` to every obstacle surface inside an
occupied voxel (the maximum over the 8 surrounding voxel centres of ``D(c) - |p - c|``, minus half a voxel
diagonal), so ``clearance(p) >= r`` proves a sphere of radius ``r`` at ``p`` free. It is at most
``sqrt(3) * resolution`` below the distance to the occupied voxels, ``2 sqrt(3) * resolution`` below that to a surface voxelised into them. Outside the map it is ``-inf`` (unknown is not free).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from cufund import _core
from cufund.mapping.esdf_map import EsdfMap

__all__ = ["ClearanceQuery"]


class ClearanceQuery:
    """Clearance and motion checks on an :class:`~cufund.mapping.EsdfMap` (a live view: map updates show) or
    on a static distance array (:meth:`from_distances`, :func:`~cufund.planning.clearance_from_world`).

    ``clearance_xyz`` and ``segment_free_xyz`` take plain floats and cross into C++ without numpy, for
    sampling-based planners that call them per state (plain builtins: about 50 ns of call overhead, no
    numpy, no pybind11 dispatch).
    """

    def __init__(self, esdf_map: EsdfMap) -> None:
        if not isinstance(esdf_map, EsdfMap):
            raise TypeError(f"esdf_map must be a cufund.mapping.EsdfMap, got {type(esdf_map).__name__}")
        self.esdf_map: EsdfMap | None = esdf_map
        """The live map, or None for a static field (:meth:`from_distances`)."""
        mp = esdf_map.params
        self._init(_core.planning.ClearanceQuery(esdf_map._core), mp.origin_W, mp.shape, mp.resolution)

    @classmethod
    def from_distances(cls, distances: npt.ArrayLike, origin_W: npt.ArrayLike, resolution: float) -> ClearanceQuery:
        """A static field: ``distances`` (nx, ny, nz) [m] from each voxel centre to the nearest occupied voxel
        centre (as :func:`cufund.mapping.edt` gives; values <= 0 mark occupied voxels), voxel (0, 0, 0) with its
        minimum corner at ``origin_W`` [m], edge ``resolution`` [m]. Copied once."""
        d = np.asarray(distances, dtype=float)
        core = _core.planning.ClearanceQuery(np.asarray(origin_W, dtype=float), float(resolution), d)
        self = cls.__new__(cls)
        self.esdf_map = None
        self._init(core, tuple(float(x) for x in np.asarray(origin_W, dtype=float)), d.shape, float(resolution))
        return self

    def _init(self, core: Any, origin_W: tuple[float, ...], shape: tuple[int, ...], resolution: float) -> None:
        self._core = core
        self._resolution = float(resolution)
        lo = np.asarray(origin_W, dtype=float)
        self._bounds = np.stack([lo, lo + np.asarray(shape) * self._resolution])
        # Plain builtins over the C++ query (no pybind11 dispatch: ~5x cheaper a call than a bound method).
        self.clearance_xyz, self.segment_free_xyz = self._core.scalar_functions()
        """``clearance_xyz(x, y, z) -> float`` [m]: the scalar fast path;
        ``segment_free_xyz(x0, y0, z0, x1, y1, z1, radius) -> bool``: the scalar motion check."""

    @property
    def resolution(self) -> float:
        """Voxel edge [m]."""
        return self._resolution

    @property
    def bounds_W(self) -> np.ndarray:
        """(2, 3) [min, max] corners of the mapped box [m]; clearance is -inf outside."""
        return self._bounds.copy()

    @property
    def min_step(self) -> float:
        """Segments must clear the radius by this much [m] to be certified free (the smallest trace step)."""
        return float(self._core.min_step)

    def clearance(self, p_W: npt.ArrayLike) -> np.ndarray | float:
        """Clearance [m] at points ``p_W`` (N, 3) -> (N,), or at one point (3,) -> float."""
        a = np.asarray(p_W, dtype=float)
        if a.shape == (3,):
            return self.clearance_xyz(float(a[0]), float(a[1]), float(a[2]))
        return self._core.clearance_many(a)

    def segment_free(self, p0_W: npt.ArrayLike, p1_W: npt.ArrayLike, radius: float) -> bool:
        """True when every point of the segment is certified at least ``radius`` [m] from obstacles."""
        a, b = _point("p0_W", p0_W), _point("p1_W", p1_W)
        return self.segment_free_xyz(
            float(a[0]), float(a[1]), float(a[2]), float(b[0]), float(b[1]), float(b[2]), float(radius)
        )

    def path_free(self, path_W: npt.ArrayLike, radius: float) -> np.ndarray:
        """Per edge of the polyline ``path_W`` (K, 3): is it certified free? (K-1,) bool."""
        return self._core.segments_free(np.asarray(path_W, dtype=float), float(radius))

    def shortcut(self, path_W: npt.ArrayLike, radius: float) -> np.ndarray:
        """Greedy line-of-sight shortcut of a free polyline (ends kept, never longer)."""
        return self._core.shortcut(np.asarray(path_W, dtype=float), float(radius))


def _point(name: str, p: npt.ArrayLike) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers [m], got {p!r}")
    return a

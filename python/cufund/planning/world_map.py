"""An ESDF map of a world's known geometry: every voxel a triangle touches is occupied (exact overlap test)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from cufund import _core
from cufund.core.limits import current
from cufund.mapping.edt import edt
from cufund.mapping.esdf_map import EsdfMap, EsdfMapParams
from cufund.worlds.world import World

from .clearance import ClearanceQuery

__all__ = ["clearance_from_world", "esdf_from_world", "world_occupancy"]


def world_occupancy(
    world: World, resolution: float = 0.1, bounds_W: npt.ArrayLike | None = None
) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Boolean grid (nx, ny, nz) of the voxels a triangle of ``world`` touches, and its origin [m].

    The box is ``bounds_W`` ((2, 3) [min, max] corners [m]; the world's bounds if None) rounded up to whole
    voxels of edge ``resolution`` [m]. The overlap test is exact (closed voxels), so every surface point in
    the box lies in a marked voxel: what makes :class:`ClearanceQuery` a certified bound on the world.
    """
    if not isinstance(world, World):
        raise TypeError(f"world must be a cufund.worlds.World, got {type(world).__name__}")
    b = world.bounds() if bounds_W is None else np.asarray(bounds_W, dtype=float)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"bounds_W must be finite [min, max] corners of shape (2, 3) with max > min, got {bounds_W!r}")
    if (
        isinstance(resolution, bool)
        or not isinstance(resolution, (int, float))
        or not (math.isfinite(resolution) and float(resolution) > 0)
    ):
        raise ValueError(f"resolution must be finite and > 0 [m], got {resolution!r}")
    shape = tuple(max(1, math.ceil(s / resolution - 1e-9)) for s in (b[1] - b[0]))
    cap = current().grid_max_voxels
    if math.prod(shape) > cap:
        raise ValueError(
            f"resolution {resolution} m over a {' x '.join(f'{s:g}' for s in b[1] - b[0])} m box gives "
            f"{' x '.join(map(str, shape))} = {math.prod(shape)} voxels, more than grid_max_voxels = "
            f"{cap} (cufund.core.limits.configure(grid_max_voxels=...))"
        )
    origin = (float(b[0][0]), float(b[0][1]), float(b[0][2]))
    occ = np.zeros(shape, dtype=bool)
    for o in world.objects:
        index = _core.planning.voxelize_triangles(origin, shape, float(resolution), o.vertices, o.triangles)
        occ.ravel()[index] = True
    return occ, origin


def esdf_from_world(
    world: World, resolution: float = 0.1, bounds_W: npt.ArrayLike | None = None, nthreads: int = 0
) -> EsdfMap:
    """An :class:`EsdfMap` (live, updatable) with every voxel of :func:`world_occupancy` set occupied."""
    occ, origin = world_occupancy(world, resolution, bounds_W)
    params = EsdfMapParams(
        resolution=float(resolution),
        size=tuple(np.asarray(occ.shape) * float(resolution)),
        origin_W=origin,
        nthreads=nthreads,
    )
    esdf = EsdfMap(params)
    if occ.any():
        esdf.set_occupied(np.argwhere(occ))
    return esdf


def clearance_from_world(
    world: World, resolution: float = 0.1, bounds_W: npt.ArrayLike | None = None, nthreads: int = 0
) -> ClearanceQuery:
    """A static :class:`ClearanceQuery` of the world's known geometry: the exact distance transform of
    :func:`world_occupancy` (much cheaper to build than an :class:`EsdfMap`, which is kept up to date)."""
    occ, origin = world_occupancy(world, resolution, bounds_W)
    return ClearanceQuery.from_distances(edt(occ, float(resolution), nthreads=nthreads), origin, float(resolution))

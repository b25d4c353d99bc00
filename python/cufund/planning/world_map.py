"""An ESDF map of a world's known geometry: every voxel a triangle touches is occupied (exact overlap test)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .. import _core
from ..mapping.esdf_map import EsdfMap, EsdfMapParams
from ..worlds.world import World

__all__ = ["esdf_from_world"]


def esdf_from_world(world: World, resolution: float = 0.1, bounds_W: npt.ArrayLike | None = None,
                    nthreads: int = 0) -> EsdfMap:
    """An :class:`EsdfMap` with every voxel that a triangle of ``world`` touches set occupied.

    Args:
        world: the meshes.
        resolution: voxel edge [m].
        bounds_W: (2, 3) [min, max] corners of the mapped box [m]; the world's bounds if None.
        nthreads: threads of the distance field (0: all cores).

    Every surface point inside the box lies in an occupied voxel, which is what makes
    :class:`~cufund.planning.ClearanceQuery` a certified lower bound on the distance to the world.
    """
    if not isinstance(world, World):
        raise TypeError(f"world must be a cufund.worlds.World, got {type(world).__name__}")
    b = world.bounds() if bounds_W is None else np.asarray(bounds_W, dtype=float)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"bounds_W must be finite [min, max] corners of shape (2, 3) with max > min, got {bounds_W!r}")
    if not (isinstance(resolution, (int, float)) and math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be finite and > 0 [m], got {resolution!r}")
    params = EsdfMapParams(resolution=float(resolution), size=tuple(b[1] - b[0]), origin_W=tuple(b[0]), nthreads=nthreads)
    esdf = EsdfMap(params)
    shape = params.shape
    index = [_core.planning.voxelize_triangles(params.origin_W, shape, params.resolution, o.vertices, o.triangles)
             for o in world.objects]
    lin = np.unique(np.concatenate(index)) if index else np.zeros(0, np.int64)
    if lin.size:
        esdf.set_occupied(np.stack(np.unravel_index(lin, shape), axis=1))
    return esdf

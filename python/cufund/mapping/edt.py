"""Exact Euclidean distance transform of boolean grids (Felzenszwalb & Huttenlocher, in C++)."""

from __future__ import annotations

import numbers

import numpy as np
import numpy.typing as npt

from cufund import _core


def edt(
    occupied: npt.ArrayLike,
    voxel_size: float | npt.ArrayLike = 1.0,
    signed: bool = False,
    nthreads: int = 0,
    dtype: npt.DTypeLike = np.float64,
) -> np.ndarray:
    """Distance from every voxel centre to the nearest occupied voxel centre.

    Exact (not an approximation by chamfer or wavefront): the separable linear-time algorithm of
    Felzenszwalb & Huttenlocher, run on ``nthreads`` threads with the GIL released. Equals
    ``scipy.ndimage.distance_transform_edt(~occupied, sampling=voxel_size)`` up to float rounding.

    Args:
        occupied: boolean (or integer, nonzero = occupied) array of 1, 2 or 3 dimensions.
        voxel_size: voxel edge length [m], one number or one per axis (anisotropic grids).
        signed: if true, occupied voxels hold minus the distance to the nearest free voxel centre
            (``edt(occ) - edt(~occ)``), so the field is negative inside obstacles.
        nthreads: worker threads; 0 uses every core.
        dtype: ``np.float64`` (default) or ``np.float32`` for the result (and the working grid).

    Returns:
        Array of ``occupied.shape`` [m]; ``inf`` everywhere when nothing is occupied (``-inf`` inside
        when everything is, with ``signed``).

    Raises:
        ValueError: a non-boolean/integer or empty ``occupied``, more than 3 dimensions, a voxel size
            that is not finite and > 0 or has the wrong length, ``nthreads < 0`` or another ``dtype``.
    """
    if isinstance(nthreads, bool) or not isinstance(nthreads, numbers.Integral) or nthreads < 0:
        raise ValueError(f"nthreads must be an integer >= 0 (0 = all cores), got {nthreads!r}")
    if not isinstance(signed, (bool, np.bool_)):
        raise ValueError(f"signed must be a bool, got {signed!r}")
    try:
        kind = np.dtype(dtype)
    except TypeError:
        raise ValueError(f"dtype must be float32 or float64, got {dtype!r}") from None
    if kind not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"dtype must be float32 or float64, got {kind}")
    return _core.esdf.edt(occupied, voxel_size, bool(signed), int(nthreads), kind == np.dtype(np.float32))

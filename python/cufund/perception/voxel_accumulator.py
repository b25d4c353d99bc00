"""A bounded map of voxel means: LiDAR points accumulated over scans for detection, the oldest forgotten first."""

from __future__ import annotations

import numpy as np

from .detection import voxel_keys

__all__ = ["VoxelAccumulator"]


class VoxelAccumulator:
    """Sums of points and unit ray directions per voxel of edge ``voxel`` [m], at most ``max_voxels`` voxels.

    :meth:`insert` adds a batch; :meth:`means` gives each voxel's mean point and mean ray direction (sorted by
    voxel, so the same inserts give the same arrays). When the bound is exceeded the voxels seen least recently
    (ties: lowest key) are dropped.
    """

    def __init__(self, voxel: float, max_voxels: int) -> None:
        if not (isinstance(voxel, (int, float)) and np.isfinite(voxel) and voxel > 0):
            raise ValueError(f"voxel must be a finite number > 0 [m], got {voxel!r}")
        if isinstance(max_voxels, bool) or not isinstance(max_voxels, (int, np.integer)) or max_voxels < 1:
            raise ValueError(f"max_voxels must be an integer >= 1, got {max_voxels!r}")
        self.voxel, self.max_voxels = float(voxel), int(max_voxels)
        self.clear()

    def clear(self) -> None:
        self._keys = np.zeros(0, dtype=np.int64)
        self._sums = np.zeros((0, 7))  # point xyz, ray xyz, count
        self._seen = np.zeros(0, dtype=np.int64)
        self.batches = 0

    def __len__(self) -> int:
        return len(self._keys)

    def insert(self, points_W: np.ndarray, rays_W: np.ndarray) -> None:
        """Adds points (N, 3) [m] and the unit directions (N, 3) of the rays that measured them."""
        points_W, rays_W = np.asarray(points_W, dtype=float), np.asarray(rays_W, dtype=float)
        if points_W.ndim != 2 or points_W.shape[1] != 3 or rays_W.shape != points_W.shape:
            raise ValueError(
                f"points_W and rays_W must both have shape (N, 3), got {points_W.shape} and {rays_W.shape}"
            )
        self.batches += 1
        if len(points_W) == 0:
            return
        # Only the voxels the batch touches are summed: each one's old sum (if any) then its new rows in input
        # order, through np.add.reduceat as a full re-reduction would (the same bits); the rest stay as they are.
        new = voxel_keys(points_W, self.voxel)
        by_key = np.argsort(new, kind="stable")
        keys = new[by_key]
        rows = np.hstack([points_W, rays_W, np.ones((len(points_W), 1))])[by_key]
        first = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        touched = keys[first]
        pos = np.searchsorted(self._keys, touched)
        known = pos < len(self._keys)
        known[known] = self._keys[pos[known]] == touched[known]
        counts = np.diff(np.r_[first, len(keys)])
        seg_len = counts + known
        seg_start = np.r_[0, np.cumsum(seg_len)[:-1]]
        block = np.empty((int(seg_len.sum()), 7))
        block[seg_start[known]] = self._sums[pos[known]]
        block[np.repeat(seg_start + known, counts) + (np.arange(len(keys)) - np.repeat(first, counts))] = rows
        sums = np.add.reduceat(block, seg_start, axis=0)
        self._sums[pos[known]] = sums[known]
        self._seen[pos[known]] = self.batches
        at = pos[~known]
        self._keys = np.insert(self._keys, at, touched[~known])
        self._sums = np.insert(self._sums, at, sums[~known], axis=0)
        self._seen = np.insert(self._seen, at, self.batches)
        if len(self._keys) > self.max_voxels:
            keep = np.sort(np.lexsort((self._keys, -self._seen))[: self.max_voxels])
            self._keys, self._sums, self._seen = self._keys[keep], self._sums[keep], self._seen[keep]

    def drop(self, mask: np.ndarray) -> None:
        """Forgets the voxels where ``mask`` (one bool per voxel, in the order of :meth:`means`) is True."""
        keep = ~np.asarray(mask, dtype=bool)
        self._keys, self._sums, self._seen = self._keys[keep], self._sums[keep], self._seen[keep]

    def means(self) -> tuple[np.ndarray, np.ndarray]:
        """Each voxel's mean point (M, 3) [m] and mean ray direction (M, 3)."""
        n = self._sums[:, 6:7]
        return self._sums[:, :3] / n, self._sums[:, 3:6] / n

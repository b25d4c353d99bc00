"""The geometry of tunnel frames as boxes: the bars (and legs) of each frame from its opening's centre, normal and
size, and the exact distance from points to them. The tunnel mission checks its plans against the *detected*
frames with it; the run's metrics measure the flown path against the *true* frames with it."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["FrameBoxes", "frame_boxes", "passages"]


class FrameBoxes:
    """Oriented boxes: ``centres`` (B, 3) [m], ``axes`` (B, 3, 3) (rows: the box's unit axes in the world),
    ``half`` (B, 3) half-extents [m], ``frame`` (B,) the frame each box belongs to."""

    def __init__(self, centres: np.ndarray, axes: np.ndarray, half: np.ndarray, frame: np.ndarray) -> None:
        self.centres, self.axes, self.half, self.frame = centres, axes, half, frame

    def distance(self, p_W: npt.ArrayLike, chunk: int = 8192) -> np.ndarray:
        """Distance [m] from each point (N, 3) to the nearest box (0 inside; inf without boxes)."""
        p = np.asarray(p_W, dtype=float).reshape(-1, 3)
        out = np.full(p.shape[0], np.inf)
        if self.centres.shape[0] == 0:
            return out
        for i in range(0, p.shape[0], chunk):
            d = p[i : i + chunk, None, :] - self.centres[None, :, :]  # (n, B, 3)
            local = np.einsum("nbk,bjk->nbj", d, self.axes)  # coordinates along the box axes
            outside = np.maximum(np.abs(local) - self.half[None], 0.0)
            out[i : i + chunk] = np.linalg.norm(outside, axis=2).min(axis=1)
        return out


def frame_boxes(
    centres_W: npt.ArrayLike, normals_W: npt.ArrayLike, sizes: npt.ArrayLike, bar: float = 0.05, legs: bool = True
) -> FrameBoxes:
    """The four bars around each opening (centre (K, 3), normal (K, 3) along the course, width x height (K, 2)
    [m]; bars ``bar`` thick and deep), the top and bottom bars spanning the posts, and with ``legs`` the two
    legs from the floor (z = 0) to the bottom bar of a frame that does not stand on the floor."""
    c = np.asarray(centres_W, dtype=float).reshape(-1, 3)
    n = np.asarray(normals_W, dtype=float).reshape(-1, 3)
    s = np.asarray(sizes, dtype=float).reshape(-1, 2)
    cen, ax, half, which = [], [], [], []
    z = np.array([0.0, 0.0, 1.0])
    for k in range(c.shape[0]):
        a = n[k] - n[k] @ z * z
        a = a / max(np.linalg.norm(a), 1e-12)  # frames stand upright: the horizontal part of the normal
        across = np.cross(z, a)
        R = np.stack([a, across, z])
        w, h, b = s[k, 0], s[k, 1], bar
        parts = [
            (np.array([0, 0, (h + b) / 2]), (b, w + 2 * b, b)),
            (np.array([0, 0, -(h + b) / 2]), (b, w + 2 * b, b)),
            (np.array([0, (w + b) / 2, 0]), (b, b, h)),
            (np.array([0, -(w + b) / 2, 0]), (b, b, h)),
        ]
        gap = c[k, 2] - h / 2 - b
        if legs and gap > 1e-9:
            for sgn in (-1.0, 1.0):
                parts.append((np.array([0, sgn * (w + b) / 2, -(h / 2 + b) - gap / 2]), (b, b, gap)))
        for off, size in parts:
            cen.append(c[k] + R.T @ off)
            ax.append(R)
            half.append(np.asarray(size, dtype=float) / 2)
            which.append(k)
    return FrameBoxes(
        np.asarray(cen, dtype=float).reshape(-1, 3),
        np.asarray(ax, dtype=float).reshape(-1, 3, 3),
        np.asarray(half, dtype=float).reshape(-1, 3),
        np.asarray(which, dtype=int),
    )


def passages(
    p_W: npt.ArrayLike, centres_W: npt.ArrayLike, normals_W: npt.ArrayLike, sizes: npt.ArrayLike
) -> list[int | None]:
    """For each frame, the index of the first sample of the path ``p_W`` (N, 3) that crosses its plane (behind
    to ahead along its normal) inside its opening; None if the path never does."""
    p = np.asarray(p_W, dtype=float).reshape(-1, 3)
    out: list[int | None] = []
    for c, n, (w, h) in zip(
        np.asarray(centres_W, float).reshape(-1, 3),
        np.asarray(normals_W, float).reshape(-1, 3),
        np.asarray(sizes, float).reshape(-1, 2),
        strict=True,
    ):
        a = np.array([n[0], n[1], 0.0])
        a /= max(np.linalg.norm(a), 1e-12)
        across = np.array([-a[1], a[0], 0.0])
        d = p - c
        ahead = d @ a
        i = np.flatnonzero((ahead[:-1] < 0) & (ahead[1:] >= 0))
        inside = [j for j in i if abs(d[j + 1] @ across) < w / 2 and abs(d[j + 1, 2]) < h / 2]
        out.append(int(inside[0]) + 1 if inside else None)
    return out

"""Depth of detected boxes from a rectified stereo pair: each box's middle is found again in the right image along
its rows (normalised cross-correlation, OpenCV's ``matchTemplate``, with a parabola through the peak for sub-pixel
disparity), and its depth is z = fx B / d.

A pair is rectified when both cameras have the same pinhole (no distortion) and the same axes, the right camera's
centre ``B`` along the left one's optical x axis (to the right): :func:`stereo_baseline` checks a rig's stated
mountings and gives ``B``.
"""

from __future__ import annotations

import cv2
import numpy as np

from cufund.geometry import Transform
from cufund.sensors.camera import R_CO, CameraIntrinsics

__all__ = ["box_disparities", "stereo_baseline"]

_MIN_SCORE = 0.6
"""Smallest normalised cross-correlation of a match that is kept [-]."""
_MIN_STD = 2.0
"""Smallest grey-level standard deviation of a box's middle that is matched at all (no texture: no match)."""


def stereo_baseline(
    left: CameraIntrinsics, right: CameraIntrinsics, T_BC_left: Transform, T_BC_right: Transform, tol: float = 1e-6
) -> float:
    """The baseline ``B`` [m] of a rectified pair, the right camera ``B`` to the right of the left one along its
    optical x axis; a ``ValueError`` naming what is wrong if the pair is not rectified (another pinhole, a
    distortion, other axes, an offset off the x axis, or the right camera on the left)."""
    kl = (left.width, left.height, left.fx, left.fy, left.cx, left.cy)
    kr = (right.width, right.height, right.fx, right.fy, right.cx, right.cy)
    if not np.allclose(kl, kr, rtol=0.0, atol=tol):
        raise ValueError(f"a stereo pair needs the same pinhole in both cameras, got {kl} and {kr}")
    if np.any(np.abs(left.distortion) > tol) or np.any(np.abs(right.distortion) > tol):
        raise ValueError("a stereo pair needs undistorted images (distortion all zero) to be taken as rectified")
    R_rel = T_BC_left.R.T @ T_BC_right.R
    if not np.allclose(R_rel, np.eye(3), atol=tol):
        raise ValueError(f"a stereo pair needs parallel cameras (the same axes), got {T_BC_left} and {T_BC_right}")
    offset_O = R_CO.T @ T_BC_left.R.T @ (np.asarray(T_BC_right.t) - np.asarray(T_BC_left.t))
    B = float(offset_O[0])
    if B <= 0 or np.any(np.abs(offset_O[1:]) > max(tol, 1e-6 * B)):
        raise ValueError(
            f"a stereo pair needs the right camera to the right of the left one along its x axis, got an offset of "
            f"{offset_O.round(6).tolist()} m in the left camera's optical frame"
        )
    return B


def _grey(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(np.ascontiguousarray(img[..., :3]).astype(np.uint8), cv2.COLOR_RGB2GRAY)
    return img.astype(np.float32)


def box_disparities(
    left: np.ndarray, right: np.ndarray, boxes_xyxy: np.ndarray, max_disparity: int = 96
) -> tuple[np.ndarray, np.ndarray]:
    """Disparity [px] of each box (pixel edges in the left image) in a rectified pair of (H, W) grey or (H, W, 3)
    RGB images: the middle half (width and height) of the box is matched along the same rows of the right image
    over disparities 0..``max_disparity``; sub-pixel from a parabola through the best score and its neighbours.
    Returns (disparity (k,), valid (k,)): not valid (NaN) where the middle has no texture, lies outside the image,
    the best match scores below 0.6 or lies at an end of the search."""
    L, R = _grey(left), _grey(right)
    if L.shape != R.shape or L.ndim != 2:
        raise ValueError(f"left and right must be images of the same size, got {L.shape} and {R.shape}")
    if isinstance(max_disparity, bool) or not isinstance(max_disparity, (int, np.integer)) or max_disparity < 2:
        raise ValueError(f"max_disparity must be an integer >= 2 [px], got {max_disparity!r}")
    h, w = L.shape
    b = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    disp = np.full(len(b), np.nan)
    for i, (u0, v0, u1, v1) in enumerate(b):
        if not np.all(np.isfinite((u0, v0, u1, v1))):
            continue
        du, dv = (u1 - u0) / 4, (v1 - v0) / 4
        c0, r0 = int(np.floor(u0 + du)), int(np.floor(v0 + dv))
        c1, r1 = max(int(np.ceil(u1 - du)), c0 + 3), max(int(np.ceil(v1 - dv)), r0 + 3)  # at least 3 x 3 px
        c0, c1, r0, r1 = max(c0, 0), min(c1, w), max(r0, 0), min(r1, h)
        if c1 - c0 < 3 or r1 - r0 < 3:
            continue
        patch = L[r0:r1, c0:c1]
        if float(patch.std()) < _MIN_STD:
            continue
        s0 = max(c0 - int(max_disparity), 0)  # the right image's point is d px left of the left image's
        strip = R[r0:r1, s0:c1]
        if strip.shape[1] < patch.shape[1] + 2:
            continue
        score = cv2.matchTemplate(strip, patch, cv2.TM_CCOEFF_NORMED)[0]  # score[j]: the patch at column s0 + j
        j = int(np.argmax(score))
        if score[j] < _MIN_SCORE or j == 0 or j == len(score) - 1:
            continue  # weak, or at an end of the search (the true match may lie beyond it)
        a, c_, e = float(score[j - 1]), float(score[j]), float(score[j + 1])
        den = a - 2 * c_ + e
        sub = 0.5 * (a - e) / den if den < 0 else 0.0
        d = c0 - (s0 + j + sub)
        if d > 0:
            disp[i] = d
    return disp, np.isfinite(disp)

"""The VIO's visual front end: KLT feature tracks on a calibrated stereo pair, with outlier rejection.

Per frame: the left image's features are tracked from the previous left image (pyramidal Lucas-Kanade,
``cv2.calcOpticalFlowPyrLK``); tracks whose previous frame had a stereo point go through a temporal RANSAC
(``cv2.solvePnPRansac`` of the previous stereo points against the new left observations: its outliers are
dropped, its rotation is the frame-to-frame visual rotation); new corners (``cv2.goodFeaturesToTrack``) fill the
image up to ``max_features``; every feature is searched along its row of the rectified pair over the depth
range's disparities (:meth:`StereoFrontEnd._stereo`: normalised cross-correlation, an unambiguous peak, a
left-right check, KLT sub-pixel refinement tracked back to the feature) and kept as a stereo observation only if
it passes. Observations leave in rectified pixel coordinates (the rectified left
camera R0, with ``K_rect`` and baseline ``baseline``), which is what GTSAM's ``StereoPoint2`` expects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from cufund.geometry import homogeneous

from .vio_params import VioParams

__all__ = ["StereoRig", "StereoFrame", "StereoFrontEnd"]

# Camera frame C (FLU) -> optical frame O (x right, y down, z forward), as cufund.sensors.camera's R_CO.
_R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


class StereoRig:
    """Rectification of the calibrated pair: ``T_B_R0`` (rectified left optical frame -> body), ``K_rect``
    (fx, fy, cx, cy of both rectified cameras) and ``baseline`` [m]. Without ``cam1`` (``mono``): cam0
    undistorted, ``K_rect`` its K, baseline 0."""

    def __init__(self, params: VioParams) -> None:
        c0, c1 = params.cam0, params.cam1
        self.size = (c0.width, c0.height)
        self.K0, self.D0 = c0.K, np.asarray(c0.distortion)
        self.mono = c1 is None
        if c1 is None:  # monocular: the undistorted camera itself
            self.R1: np.ndarray = np.eye(3)
            self.P1: np.ndarray = np.hstack([self.K0, np.zeros((3, 1))])
            self.K_rect, self.baseline = self.K0.copy(), 0.0
            self.T_B_R0 = homogeneous(c0.T_BC)
            self.T_B_R0[:3, :3] = self.T_B_R0[:3, :3] @ _R_CO
            return
        T_BO = []
        for cam in (c0, c1):
            T = homogeneous(cam.T_BC)
            T[:3, :3] = T[:3, :3] @ _R_CO
            T_BO.append(T)
        T_O1O0 = np.linalg.inv(T_BO[1]) @ T_BO[0]
        self.K1, self.D1 = c1.K, np.asarray(c1.distortion)
        if np.linalg.norm(T_O1O0[:3, 3]) < 1e-3:
            raise ValueError("the stereo cameras are less than 1 mm apart: no baseline to triangulate on")
        R1, R2, P1, P2, *_ = cv2.stereoRectify(
            self.K0,
            self.D0,
            self.K1,
            self.D1,
            self.size,
            T_O1O0[:3, :3],
            T_O1O0[:3, 3:].copy(),
            flags=cv2.CALIB_ZERO_DISPARITY,
            alpha=0,
        )
        if abs(P2[1, 3]) > abs(P2[0, 3]):
            raise ValueError("the stereo pair is vertical: give cam1 beside cam0 (left-right)")
        if P2[0, 3] > 0:
            raise ValueError("cam1 is left of cam0: cam0 must be the left camera of the pair")
        self.R1, self.R2, self.P1, self.P2 = R1, R2, P1, P2
        self.K_rect = P1[:3, :3].copy()
        self.baseline = float(-P2[0, 3] / P2[0, 0])
        self.T_B_R0 = T_BO[0].copy()
        self.T_B_R0[:3, :3] = T_BO[0][:3, :3] @ R1.T

    def rectify(self, uv: np.ndarray, right: bool = False) -> np.ndarray:
        """Raw pixels (N, 2) -> rectified pixels (N, 2)."""
        if len(uv) == 0:
            return np.zeros((0, 2))
        K, D, R, P = (self.K1, self.D1, self.R2, self.P2) if right else (self.K0, self.D0, self.R1, self.P1)
        return cv2.undistortPoints(uv.reshape(-1, 1, 2).astype(np.float64), K, D, R=R, P=P).reshape(-1, 2)

    def triangulate(self, uvl: np.ndarray, uvr: np.ndarray) -> np.ndarray:
        """Rectified stereo pixels -> points in the rectified left optical frame (N, 3) [m]."""
        f, cx, cy = self.K_rect[0, 0], self.K_rect[0, 2], self.K_rect[1, 2]
        fy = self.K_rect[1, 1]
        z = f * self.baseline / (uvl[:, 0] - uvr[:, 0])
        return np.column_stack([(uvl[:, 0] - cx) * z / f, (uvl[:, 1] - cy) * z / fy, z])


@dataclass
class StereoFrame:
    """What the front end made of one stereo frame."""

    t: float
    ids: np.ndarray
    """Track ids (N,)."""
    uv_left: np.ndarray
    """Rectified left pixels (N, 2)."""
    uv_right: np.ndarray
    """Rectified right pixels (N, 2), NaN where the feature has no stereo match."""
    tracked: int
    """Features carried over from the previous frame (after the RANSAC)."""
    inliers: int
    """Temporal RANSAC inliers (0 when it could not run)."""
    R_cur_prev: np.ndarray | None
    """Visual rotation: points of the previous rectified left frame into this one's (None: no RANSAC)."""
    time_ms: float = 0.0

    @property
    def stereo(self) -> np.ndarray:
        """Mask of the features with a stereo observation."""
        return ~np.isnan(self.uv_right[:, 0])


def to_gray(image: np.ndarray, size: tuple[int, int], name: str) -> np.ndarray:
    """A uint8 grey image of ``size`` (width, height) from an (H, W) or (H, W, 3) uint8 image; anything else is a
    ValueError naming ``name``, the shape and dtype expected."""
    img = np.asarray(image)
    w, h = size
    if img.dtype != np.uint8:
        raise ValueError(f"{name}: expected a uint8 image, got dtype {img.dtype}")
    if img.shape not in ((h, w), (h, w, 3)):
        raise ValueError(f"{name}: expected shape ({h}, {w}) or ({h}, {w}, 3), got {img.shape}")
    return cv2.cvtColor(img, cv2.COLOR_RGB2GRAY) if img.ndim == 3 else img


class StereoFrontEnd:
    """``process(t, left, right)`` per stereo frame -> :class:`StereoFrame`."""

    def __init__(self, params: VioParams, rig: StereoRig) -> None:
        self.params, self.rig = params, rig
        p = params
        self._lk: dict[str, Any] = {
            "winSize": (p.klt_window_px, p.klt_window_px),
            "maxLevel": p.klt_levels,
            "criteria": (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01),
        }
        self._maps: tuple | None = None
        self.reset()

    def reset(self) -> None:
        self._prev_gray: np.ndarray | None = None
        self._prev_pyr: np.ndarray | None = None
        self._ids = np.zeros(0, dtype=np.int64)
        self._raw = np.zeros((0, 2), dtype=np.float32)  # raw left pixels of the tracked features
        self._X_prev: dict[int, np.ndarray] = {}  # stereo points of the previous frame (rectified left frame)
        self._next_id = 0

    def process(self, t: float, left: np.ndarray, right: np.ndarray | None = None) -> StereoFrame:
        """A stereo frame, or a monocular one (``right`` None, which a monocular rig requires)."""
        import time

        wall = time.perf_counter()
        p, rig = self.params, self.rig
        g0 = to_gray(left, rig.size, "left image")
        if (right is None) != rig.mono:
            raise ValueError("right image: a stereo rig needs one, a monocular rig (no cam1) takes None")
        g1 = to_gray(right, rig.size, "right image") if right is not None else None
        w, h = rig.size
        ids, raw = self._ids, self._raw
        pyr0 = g0
        R_cur_prev = None
        inliers = 0
        if self._prev_pyr is not None and len(raw):
            nxt, st, err = cv2.calcOpticalFlowPyrLK(self._prev_pyr, pyr0, raw.reshape(-1, 1, 2), None, **self._lk)  # type: ignore[call-overload]
            nxt = nxt.reshape(-1, 2)
            ok = (st.reshape(-1) == 1) & (err.reshape(-1) < p.klt_max_error)
            ok &= (nxt[:, 0] >= 0) & (nxt[:, 0] <= w - 1) & (nxt[:, 1] >= 0) & (nxt[:, 1] <= h - 1)
            ids, raw = ids[ok], nxt[ok]
            # temporal RANSAC: the previous frame's stereo points against the new observations
            has3d = np.array([i in self._X_prev for i in ids.tolist()], dtype=bool)
            keep = np.ones(len(ids), dtype=bool)
            if np.count_nonzero(has3d) >= 6:
                X = np.array([self._X_prev[i] for i in ids[has3d].tolist()])
                uv = rig.rectify(raw[has3d])
                found, rvec, tvec, inl = cv2.solvePnPRansac(
                    X,
                    uv,
                    rig.K_rect,
                    None,
                    reprojectionError=p.ransac_px,
                    iterationsCount=100,
                    confidence=0.999,
                    flags=cv2.SOLVEPNP_AP3P,
                )
                if found and inl is not None and len(inl) >= 6:
                    mask = np.zeros(len(X), dtype=bool)
                    mask[inl.reshape(-1)] = True
                    rvec, tvec = cv2.solvePnPRefineLM(X[mask], uv[mask], rig.K_rect, None, rvec, tvec)
                    R_cur_prev = cv2.Rodrigues(rvec)[0]
                    inliers = int(mask.sum())
                    keep[np.flatnonzero(has3d)[~mask]] = False
                else:
                    keep[has3d] = False
            elif len(ids) >= 8:  # too few stereo points: epipolar RANSAC on the rectified tracks
                prev_uv = rig.rectify(self._raw[np.isin(self._ids, ids)])
                _, mask = cv2.findFundamentalMat(prev_uv, rig.rectify(raw), cv2.FM_RANSAC, p.ransac_px, 0.999)
                if mask is not None:
                    keep = mask.reshape(-1).astype(bool)
                    inliers = int(keep.sum())
            ids, raw = ids[keep], raw[keep]
        tracked = len(ids)
        # new corners away from the tracked ones
        if len(ids) < p.max_features:
            mask = np.full((h, w), 255, dtype=np.uint8)
            r = int(p.min_feature_distance_px)
            for u, v in raw.astype(int).tolist():
                cv2.circle(mask, (u, v), r, 0, -1)
            new = cv2.goodFeaturesToTrack(
                g0, p.max_features - len(ids), 0.01, p.min_feature_distance_px, mask=mask, blockSize=5
            )
            if new is not None:
                new = new.reshape(-1, 2).astype(np.float32)
                ids = np.concatenate([ids, np.arange(self._next_id, self._next_id + len(new))])
                self._next_id += len(new)
                raw = np.concatenate([raw, new])
        # stereo matches on the epipolar line
        uvl = rig.rectify(raw)
        uvr = self._stereo(pyr0, g1, raw, uvl) if g1 is not None else np.full_like(uvl, np.nan)
        st_mask = ~np.isnan(uvr[:, 0])
        X = rig.triangulate(uvl[st_mask], uvr[st_mask]) if st_mask.any() else np.zeros((0, 3))
        self._X_prev = dict(zip(ids[st_mask].tolist(), X, strict=True))
        self._ids, self._raw, self._prev_pyr = ids, raw.astype(np.float32), pyr0
        return StereoFrame(t, ids.copy(), uvl, uvr, tracked, inliers, R_cur_prev, (time.perf_counter() - wall) * 1e3)

    def _stereo(self, g0: np.ndarray, g1: np.ndarray, raw: np.ndarray, uvl: np.ndarray) -> np.ndarray:
        """Rectified right pixels (N, 2) of the left features ``raw`` (rectified ``uvl``), NaN where no match
        passes. Each feature is searched along its rectified row over the disparity range (normalised
        cross-correlation of a ``stereo_patch_px`` patch): the best score must reach ``stereo_min_ncc`` and beat
        every other peak by ``stereo_ncc_margin`` (a repetitive texture's ambiguous match is dropped, not guessed);
        KLT refines it to sub-pixel and it is kept only when KLT tracks it back to the feature within
        ``stereo_fb_px``. The right patch is searched back along the row the same way and must find the feature
        (a left-right check: a pattern cut by the image border looks unique from one side only). KLT alone from a
        zero-disparity guess reached no match for near objects (a disparity beyond its pyramid) and settled on
        another patch of the same row for about two matches in three in the tunnel's frames: a wrong depth the
        epipolar check cannot see."""
        p, rig = self.params, self.rig
        n = len(raw)
        uvr = np.full((n, 2), np.nan)
        if n == 0:
            return uvr
        fb_max = rig.K_rect[0, 0] * rig.baseline
        d_lo, d_hi = fb_max / p.max_depth, fb_max / p.min_depth
        # the row search, in the rectified pair
        gr0, gr1 = self._rectified(g0, g1)
        found, guess_l, guess_r = [], [], []
        for i in range(n):
            ui, vi = int(round(float(uvl[i, 0]))), int(round(float(uvl[i, 1])))
            ur = self._row_peak(gr0, gr1, ui, vi, ui - d_hi, ui - d_lo)
            if ur is None:
                continue
            back = self._row_peak(gr1, gr0, ur, vi, ur + d_lo, ur + d_hi)  # and from the right image back
            if back is None or abs(back - ui) > 1:
                continue  # the peak seen from the right is another one: a repetitive or out-of-view patch
            found.append(i)
            guess_l.append((ui, vi))
            guess_r.append((ur, vi))
        if not found:
            return uvr
        idx = np.array(found)
        pl = np.asarray(guess_l, dtype=np.float32) + (uvl[idx] - np.round(uvl[idx])).astype(np.float32)
        pr = np.asarray(guess_r, dtype=np.float32) + (pl - np.asarray(guess_l, dtype=np.float32))
        lk0 = {**self._lk, "maxLevel": 0}  # the search put it within a pixel: no pyramid to jump elsewhere
        m, st, err = cv2.calcOpticalFlowPyrLK(
            gr0, gr1, pl.reshape(-1, 1, 2), pr.reshape(-1, 1, 2).copy(), flags=cv2.OPTFLOW_USE_INITIAL_FLOW, **lk0
        )
        m = m.reshape(-1, 2)
        ok2 = self._checked(gr0, gr1, pl, m, st, err, d_lo, d_hi, lk0)
        ok2 &= np.abs(m[:, 0] - pr[:, 0]) < 1.5  # KLT stayed on the searched peak
        uvr[idx[ok2]] = m[ok2].astype(np.float64) + (uvl[idx[ok2]] - pl[ok2])
        return uvr

    def _row_peak(self, src: np.ndarray, dst: np.ndarray, u: int, v: int, u_lo: float, u_hi: float) -> int | None:
        """The column in ``dst``'s row ``v`` between ``u_lo`` and ``u_hi`` whose patch best correlates with
        ``src``'s patch at (u, v), or None when the best score is below ``stereo_min_ncc`` or another peak (outside
        the best one's lobe) comes within ``stereo_ncc_margin`` of it."""
        p = self.params
        r = p.stereo_patch_px // 2
        h, w = dst.shape
        if not (r <= u < w - r and r <= v < h - r):
            return None
        lo = max(int(math.floor(u_lo)) - r, 0)
        hi = min(int(math.ceil(u_hi)) + r + 1, w)
        if hi - lo < 2 * r + 3:
            return None
        score = cv2.matchTemplate(
            dst[v - r : v + r + 1, lo:hi], src[v - r : v + r + 1, u - r : u + r + 1], cv2.TM_CCOEFF_NORMED
        ).reshape(-1)
        j = int(np.argmax(score))
        best = float(score[j])
        if best < p.stereo_min_ncc:
            return None
        a, b = j, j  # the peak's own lobe: down both sides while the score falls
        while a > 0 and score[a - 1] < score[a]:
            a -= 1
        while b < len(score) - 1 and score[b + 1] < score[b]:
            b += 1
        others = np.concatenate([score[:a], score[b + 1 :]])
        if len(others) and float(others.max()) > best - p.stereo_ncc_margin:
            return None  # ambiguous: a repetitive texture or a featureless row
        return lo + j + r

    def _checked(
        self,
        g0: np.ndarray,
        g1: np.ndarray,
        src: np.ndarray,
        m1: np.ndarray,
        st: np.ndarray,
        err: np.ndarray,
        d_lo: float,
        d_hi: float,
        lk: dict[str, Any],
    ) -> np.ndarray:
        """Mask of the left-to-right matches ``m1`` of ``src`` (both in the rectified pair ``g0``, ``g1``) that KLT
        found, that lie on their epipolar row within the disparity range, and that KLT tracks back to ``src``
        within ``stereo_fb_px``."""
        p = self.params
        ok = (st.reshape(-1) == 1) & (err.reshape(-1) < p.klt_max_error)
        uvl, r1 = src.astype(np.float64), m1.astype(np.float64)
        disp = uvl[:, 0] - r1[:, 0]
        ok &= np.abs(uvl[:, 1] - r1[:, 1]) < p.stereo_epipolar_px
        ok &= (disp > d_lo) & (disp < d_hi)
        if ok.any():
            sel = np.flatnonzero(ok)
            back, st2, _ = cv2.calcOpticalFlowPyrLK(
                g1,
                g0,
                m1[sel].reshape(-1, 1, 2).astype(np.float32),
                src[sel].reshape(-1, 1, 2).astype(np.float32).copy(),
                flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
                **lk,
            )
            fb = np.linalg.norm(back.reshape(-1, 2) - src[sel], axis=1)
            ok[sel] = (st2.reshape(-1) == 1) & (fb < p.stereo_fb_px)
        return ok

    def _rectified(self, g0: np.ndarray, g1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Both images rectified (rows are epipolar lines); the maps are made once."""
        if self._maps is None:
            rig = self.rig
            self._maps = tuple(
                cv2.initUndistortRectifyMap(K, D, R, P, rig.size, cv2.CV_16SC2)
                for K, D, R, P in ((rig.K0, rig.D0, rig.R1, rig.P1), (rig.K1, rig.D1, rig.R2, rig.P2))
            )
        (a0, a1), (b0, b1) = self._maps
        return cv2.remap(g0, a0, a1, cv2.INTER_LINEAR), cv2.remap(g1, b0, b1, cv2.INTER_LINEAR)

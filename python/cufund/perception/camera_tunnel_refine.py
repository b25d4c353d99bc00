"""A detector's loose box around a tunnel frame refined to the frame's own edges in a rectified stereo pair (issue 26,
item 4a): the detector gives the region, the image and the stereo geometry give the edges.

A frame's bars are plain: one albedo, which light and shade only scale (a side face, a shadow), so one chromaticity
(255 rgb / (r + g + b)); what lies behind them is textured. Over the middle rows of the box each vertical bar is a
run of columns whose pixels agree down the rows. In an enlarged window around each of the box's vertical edges:

1. **Bars.** Runs of at least 2 columns that vary down the rows by less than a quarter of the window's typical
   column, of one chromaticity, with a contrast to what lies outside their outer edge. Each run's outer edge is
   found to a fraction of a pixel: in each row, where the bar's chromaticity ends (a slanted edge moves it from row
   to row; a side face in another shade is the bar's), averaged over the rows.
2. **Their disparity.** The runs of the right image along the same rows of the same chromaticity, at least a
   bar's face wide at their disparity, whose outer edge lies at a disparity the box's height and the run's width
   allow (a bar's silhouette is at least its face, fx bar / z = d bar / B, wide). The disparity is the outer edges'
   difference: what lies just outside a frame's outer edge is farther, so the edge is the bar's own silhouette in
   both images. Every such run is a candidate: first those one bar wide at their disparity, then the most alike in
   width (a run of several frames' bars merged is wider, and merges differently in the other image).
3. **Top and bottom.** The bars' top ends: where their faces' middle columns stop being bar-coloured at the
   frame's disparity in both images (a bar of a frame behind, stacked above it in the left image, lies elsewhere in
   the right one); the top line joins them, and the top bar must run along it between the bars (a longer top bar
   of a frame behind may lie along it in the image). The bottom bar: in the columns between the bars, the lowest
   bar-coloured run as thick as a bar at the frame's disparity (frames behind stand farther and are seen higher),
   on one line over half the columns at least, meeting both vertical bars and ending at the outer edges; else the
   next one up.
4. **A frame.** The pair's outer edges at their depths must make a frame turned by at most ``max_yaw_deg`` from
   the view, and its top corners must lie at one height, and its bottom corners (frames stand upright; the world's
   up from the estimate): two frames' bars, or another frame's bottom bar, are refused so.

Of the pairs that pass, the one whose outline is nearest the detector's box is kept. None: the box gives no
measurement (rather than a wrong frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RefinedBox", "refine_frame_box"]

_MIN_CONTRAST = 10.0
"""Smallest colour difference between a bar and what lies beside it [8-bit digital numbers]."""
_BAND = 0.3
"""The bars are found over the box's rows less this share at the top and at the bottom [-]."""
_MIN_COVER = 0.85
"""Share of the columns between the bars that the top bar must cover [-]."""
_MIN_BOTTOM = 0.5
"""Share of the columns between the bars where the bottom bar's lower edge must be found on one line [-] (legs and
bars of frames behind cross it)."""


@dataclass(frozen=True)
class RefinedBox:
    """A frame's outline in the left image [px, pixel edges]."""

    box_xyxy: tuple[float, float, float, float]
    """(outer left edge of the left bar, top at the nearer bar, outer right edge of the right bar, bottom at the
    nearer bar)."""
    disparities: tuple[float, float]
    """The left and right bars' disparities from their outer edges [px]."""
    top: tuple[float, float]
    """The top line v = top[0] + top[1] u [px]."""
    bottom: tuple[float, float]
    """The bottom line v = bottom[0] + bottom[1] u [px]."""
    single: bool = True
    """Whether both bars' runs in the right image are as wide as one bar at their disparity (not several frames'
    bars merged, whose outer edge may be matched to another run's)."""
    partial: bool = False
    """Whether the bottom bar was not found (merged with a nearer frame's bar across it) and the bottom is the
    rules' square opening's, confirmed at the two bottom corners (``partial_min_width``)."""


@dataclass(frozen=True)
class _Bar:
    outer: float
    """Sub-pixel outer edge (left edge of a left bar, right edge of a right bar) [px]."""
    inner: float
    a: int
    b: int
    """Columns [a, b) of the run."""
    colour: np.ndarray
    tol: float
    """Largest colour difference of a pixel still taken for the bar's [DN]."""


def _image(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the image as (H, W, C) floats, each pixel's chromaticity: 255 rgb / (r + g + b); grey images: the grey).
    A bar's albedo is one colour; light and shade scale it (a side face, a shadow), which leaves its chromaticity."""
    a = np.asarray(img, dtype=np.float32)
    if a.ndim == 2:
        return a[..., None], a[..., None]
    a = a[..., :3]
    return a, 255.0 * a / np.maximum((a[..., 0] + a[..., 1] + a[..., 2])[..., None], 1.0)  # (faster than .sum)


def _norm(x: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(x, axis=-1)`` to the bit, the squares of the few channels added one by one: numpy's
    reduction over a last axis of 3 took most of a box's refinement."""
    s = x[..., 0] * x[..., 0]
    for c in range(1, x.shape[-1]):
        s = s + x[..., c] * x[..., c]
    return np.sqrt(s)


def _runs(img: tuple[np.ndarray, np.ndarray], rows: slice, c0: int, c1: int, side: str) -> list[_Bar]:
    """Plain vertical runs in columns [c0, c1) over ``rows`` (see the module's step 1) of ``img`` (:func:`_image`);
    ``side`` 'left' or 'right' names which edge is the outer one."""
    rgb = img[0][rows, c0:c1]
    band = img[1][rows, c0:c1]
    if band.shape[0] < 3 or band.shape[1] < 6:
        return []
    S = _norm(rgb - rgb.mean(axis=0)).mean(axis=0)  # how much each column varies down the rows
    P = band.mean(axis=0)  # (n, C) each column's mean chromaticity
    s_thr = max(2.0, 0.25 * float(np.percentile(S, 80)))
    plain = S < s_thr
    out: list[_Bar] = []
    n = len(S)
    j = 0
    while j < n:
        if not plain[j]:
            j += 1
            continue
        k = j + 1
        while k < n and plain[k] and np.linalg.norm(P[k] - P[j]) < 0.5 * _MIN_CONTRAST:
            k += 1
        if k - j >= 2 and j >= 2 and k <= n - 2:
            colour = P[j:k].mean(axis=0)
            beside = P[j - 2] if side == "left" else P[k + 1]  # outside the outer edge (inside: maybe another bar)
            contrast = float(np.linalg.norm(colour - beside))
            if contrast >= _MIN_CONTRAST:
                tol = 0.5 * contrast
                mask = _norm(band - colour) < tol  # (rows, n) bar-coloured pixels
                mid = (j + k) // 2
                # per row, the bar-coloured segment through the run's middle column (a side face in another
                # shade included): its ends, averaged
                reach = max(3, k - j)
                lo = max(j - reach, 0)
                left_part = mask[:, lo:mid][:, ::-1]
                first_off = np.where(left_part.all(axis=1), left_part.shape[1], np.argmin(left_part, axis=1))
                left_edge = float(np.mean(mid - first_off))
                hi = min(k + reach, n)
                right_part = mask[:, mid:hi]
                first_off = np.where(right_part.all(axis=1), right_part.shape[1], np.argmin(right_part, axis=1))
                right_edge = float(np.mean(mid + first_off))
                if side == "left":
                    outer, inner = left_edge, right_edge
                else:
                    outer, inner = right_edge, left_edge
                if not any(abs(b.outer - c0 - outer) < 0.5 for b in out):  # a side face's run: the same bar
                    out.append(_Bar(c0 + outer, c0 + inner, c0 + j, c0 + k, colour, tol))
        j = k
    return out


def _disparities(
    bar: _Bar, right_bars: list[_Bar], B_over_bar: float, span: tuple[float, float]
) -> list[tuple[float, bool]]:
    """The outer edges' differences to the runs of the right image that may be ``bar`` (module step 2), each with
    whether that run is as wide as one bar seen at that disparity (its face, up to its side face more); those
    first, then the run of the most alike width (a run of several frames' bars merged is wider, and merges
    differently in the other image)."""
    w = abs(bar.inner - bar.outer)
    hi = min(span[1], B_over_bar * (w + 1.5))  # a bar's silhouette is at least its face: fx bar / z = d bar / B
    found = []
    for r in right_bars:
        d = bar.outer - r.outer
        wr = abs(r.inner - r.outer)
        face = d / B_over_bar
        if not span[0] <= d <= hi or wr < face - 1.5 or np.linalg.norm(r.colour - bar.colour) > bar.tol:
            continue
        single = wr <= 1.45 * face + 1.5
        found.append((not single, abs(wr - w), d))
    return [(d, not merged) for merged, _, d in sorted(found)]


def _column_runs(mask: np.ndarray) -> list[list[tuple[int, int]]]:
    """Each column's runs [start, end) of True rows."""
    out = []
    for col in mask.T:
        x = np.diff(np.concatenate([[0], col.astype(np.int8), [0]]))
        starts, ends = np.nonzero(x == 1)[0], np.nonzero(x == -1)[0]
        out.append(list(zip(starts.tolist(), ends.tolist(), strict=True)))
    return out


def _fit(us: np.ndarray, vs: np.ndarray) -> tuple[float, float] | None:
    """A line v = c0 + c1 u through the points, refitted without those off it by more than 3 median residuals."""
    if len(us) < 3:
        return None
    A = np.stack([np.ones_like(us), us], axis=1)
    coef, *_ = np.linalg.lstsq(A, vs, rcond=None)
    res = vs - A @ coef
    keep = np.abs(res) <= max(1.0, 3.0 * float(np.median(np.abs(res))))
    if keep.sum() < 3:
        return None
    coef, *_ = np.linalg.lstsq(A[keep], vs[keep], rcond=None)
    return float(coef[0]), float(coef[1])


def _level(
    top: tuple[float, float],
    bottom: tuple[float, float],
    left: tuple[float, float],
    right: tuple[float, float],
    f: float,
    cx: float,
    cy: float,
    up: np.ndarray,
    fB: float,
) -> bool:
    """Whether the top line's points at the two bars' outer edges ``left`` and ``right`` ((column, depth) each) lie
    at one height, and the bottom line's: within 3 cm and what one pixel of disparity moves each [m]."""
    for line in (top, bottom):
        heights, spread = [], 0.03
        for u, z in (left, right):
            v = line[0] + line[1] * u
            ray = np.array([(u - cx) / f, (v - cy) / f, 1.0])
            heights.append(z * float(ray @ up))
            spread += abs(float(ray @ up)) * z * z / fB  # a pixel of disparity moves the depth by z^2 / (f B)
        if abs(heights[0] - heights[1]) > spread:
            return False
    return True


def refine_frame_box(
    box_xyxy: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    baseline: float,
    bar: float,
    span: tuple[float, float],
    fx: float,
    cx: float,
    cy: float,
    up_O: np.ndarray | None = None,
    margin: float = 0.2,
    max_yaw_deg: float = 40.0,
    partial_min_width: float = 0.0,
) -> RefinedBox | None:
    """The frame's outline near the loose box ``box_xyxy`` (u_min, v_min, u_max, v_max pixel edges of the ``left``
    image) in the rectified pair (``left``, ``right``: (H, W) grey or (H, W, 3) RGB) whose right camera is
    ``baseline`` [m] to the left one's right; ``bar`` the bars' thickness [m], ``span`` the (min, max) disparities
    a frame can have [px], ``fx``, ``cx``, ``cy`` the left camera's focal length (fx = fy) and principal point [px],
    ``up_O`` the world's up in the left camera's optical frame (x right, y down, z along the view; default: a level
    camera's (0, -1, 0)), from the estimate; the box's
    vertical edges are searched within ``margin`` of its width (at least 10 px) either side, its top and bottom within
    twice that of its height (a detector's box is looser there). A pair of bars whose outer edges make a frame turned
    by more than ``max_yaw_deg`` from the view is refused (two frames' bars). None when no pair fits (see the
    module). The frame's top corners must be level, and its bottom corners (the frames stand upright): a pair of
    two frames' bars, or another frame's bottom bar, is not.

    ``partial_min_width`` > 0 [m]: a pair of bars with their top found (ends in both images, level, the top bar
    along the top line) whose bottom bar is not (merged with a nearer frame's bar across it: a big frame seen
    behind a small one) is kept when its opening is at least this wide, its bottom where the rules' square
    opening puts it (openings 1 m wide or more are square), and that bottom confirmed at both corners: within the
    image, bar-coloured just inside each vertical bar at the frame's disparity in both images, and not outside
    the outer edges (:attr:`RefinedBox.partial`). Such an outline is kept only if no whole one is found."""
    up = np.array([0.0, -1.0, 0.0]) if up_O is None else np.asarray(up_O, dtype=float) / np.linalg.norm(up_O)
    u0, v0, u1, v1 = (float(x) for x in np.asarray(box_xyxy, dtype=float).reshape(4))
    w, h = u1 - u0, v1 - v0
    mu, mv = max(10.0, margin * w), max(10.0, 2.5 * margin * h)
    reach = mu + 2.0 * span[1] * bar / baseline + 4.0  # a run whose outer edge is within mu, and its width
    # only the part of the pair searched (converting whole images took most of the time)
    H, W = np.asarray(left).shape[:2]
    ox, oy = max(int(math.floor(u0 - reach - span[1] - 8.0)), 0), max(int(math.floor(v0 - mv - 2.0)), 0)
    ox1, oy1 = min(int(math.ceil(u1 + reach + 8.0)), W), min(int(math.ceil(v1 + mv + 2.0)), H)
    if partial_min_width > 0:  # a square frame's bottom corners may lie below the window searched
        oy1 = H
    if ox1 - ox < 8 or oy1 - oy < 8:
        return None
    L, R = _image(np.asarray(left)[oy:oy1, ox:ox1]), _image(np.asarray(right)[oy:oy1, ox:ox1])
    found = _refine(
        (u0 - ox, v0 - oy, u1 - ox, v1 - oy),
        L,
        R,
        baseline,
        bar,
        span,
        fx,
        cx - ox,
        cy - oy,
        up,
        mu,
        mv,
        reach,
        max_yaw_deg,
        partial_min_width,
    )
    if found is None:
        return None
    bx, (t0, t1), (b0, b1) = found.box_xyxy, found.top, found.bottom
    return RefinedBox(
        (bx[0] + ox, bx[1] + oy, bx[2] + ox, bx[3] + oy),
        found.disparities,
        (t0 + oy - t1 * ox, t1),
        (b0 + oy - b1 * ox, b1),
        found.single,
        found.partial,
    )


def _refine(
    box: tuple[float, float, float, float],
    L: tuple[np.ndarray, np.ndarray],
    R: tuple[np.ndarray, np.ndarray],
    baseline: float,
    bar: float,
    span: tuple[float, float],
    fx: float,
    cx: float,
    cy: float,
    up: np.ndarray,
    mu: float,
    mv: float,
    reach: float,
    max_yaw_deg: float,
    partial_min_width: float = 0.0,
) -> RefinedBox | None:
    """:func:`refine_frame_box` in the part of the pair searched (pixel coordinates in it)."""
    h_img, w_img = L[0].shape[:2]
    u0, v0, u1, v1 = box
    h = v1 - v0
    rows = slice(int(round(v0 + _BAND * h)), int(round(v1 - _BAND * h)))
    if rows.stop - rows.start < 3:
        return None
    B_over_bar = baseline / bar

    sides = {}
    for side, edge in (("left", u0), ("right", u1)):
        lo, hi = (edge - mu - 4.0, edge + reach) if side == "left" else (edge - reach, edge + mu + 4.0)
        c0, c1 = max(int(math.floor(lo)), 0), min(int(math.ceil(hi)), w_img)
        lbars = [b for b in _runs(L, rows, c0, c1, side) if abs(b.outer - edge) <= mu]
        rbars = _runs(R, rows, max(c0 - int(math.ceil(span[1])) - 2, 0), c1, side)
        sides[side] = [
            (b, k, d, single) for b in lbars for k, (d, single) in enumerate(_disparities(b, rbars, B_over_bar, span))
        ]
    best: tuple[tuple[bool, float, int], RefinedBox] | None = None
    mid = (rows.start + rows.stop) // 2
    window = (max(int(math.floor(v0 - mv)), 0), min(int(math.ceil(v1 + mv)), h_img))
    for lb, kl, dl, single_l in sides["left"]:
        for rb, kr, dr, single_r in sides["right"]:
            if rb.inner - lb.inner < 4:
                continue
            # the frame's turn from the two bars' outer edges at their depths: a pair of two frames' bars is
            # usually turned far more than a frame seen from before it
            z_l, z_r = fx * baseline / dl, fx * baseline / dr
            x_l, x_r = (lb.outer - cx) * z_l / fx, (rb.outer - cx) * z_r / fx
            if math.degrees(math.atan2(abs(z_r - z_l), max(x_r - x_l, 1e-9))) > max_yaw_deg:
                continue
            outer_m = math.hypot(x_r - x_l, z_r - z_l)  # the outer width [m]
            partial = partial_min_width > 0 and outer_m - 2.0 * bar >= partial_min_width
            cand = _outline(L, R, (lb, dl), (rb, dr), mid, window, B_over_bar, partial)
            if cand is None:
                continue
            top, found_bottom = cand
            bottom = found_bottom
            if bottom is None:  # the square opening's bottom, confirmed at its corners
                bottom = _square_bottom(L, R, top, (lb, dl, z_l), (rb, dr, z_r), outer_m, fx, cx, cy, up, B_over_bar)
                if bottom is None:
                    continue
            if not _level(top, bottom, (lb.outer, z_l), (rb.outer, z_r), fx, cx, cy, up, fx * baseline):
                continue
            u_near = lb.outer if dl >= dr else rb.outer  # the nearer bar's corner is the box's top and bottom
            box = (lb.outer, top[0] + top[1] * u_near, rb.outer, bottom[0] + bottom[1] * u_near)
            if box[3] - box[1] < 8:
                continue
            # nearest the detector's box; of one pair of bars, the right-image runs of the most alike widths
            cost = (
                found_bottom is None,  # a whole outline first
                abs(box[0] - u0) + abs(box[2] - u1) + abs(box[1] - v0) + abs(box[3] - v1),
                kl + kr,
            )
            if best is None or cost < best[0]:
                best = (cost, RefinedBox(box, (dl, dr), top, bottom, single_l and single_r, found_bottom is None))
    return None if best is None else best[1]


def _outline(
    L: tuple[np.ndarray, np.ndarray],
    R: tuple[np.ndarray, np.ndarray],
    lb: tuple[_Bar, float],
    rb: tuple[_Bar, float],
    mid: int,
    window: tuple[int, int],
    B_over_bar: float,
    partial: bool = False,
) -> tuple[tuple[float, float], tuple[float, float] | None] | None:
    """The top and bottom lines of the frame whose bars are ``lb`` and ``rb`` (each with its disparity), searched
    in rows ``window`` (module step 3). ``partial``: the top line with None for the bottom when the top is found
    and the bottom bar is not."""
    (bl, dl), (br, dr) = lb, rb
    colour, tol = 0.5 * (bl.colour + br.colour), min(bl.tol, br.tol)
    if np.linalg.norm(bl.colour - br.colour) > tol:
        return None  # the two bars of one frame look alike
    t0, t1 = window
    h_img, w_img = L[1].shape[:2]

    def disparity(u: np.ndarray) -> np.ndarray:  # the frame's plane: linear in u between the bars
        return np.interp(u, [bl.outer, br.outer], [dl, dr])

    # the bars' top ends: where their middle columns stop being bar-coloured at the frame's disparity in both
    # images (another frame's bar stacked above it in the left image lies elsewhere in the right one)
    tops, centres = [], []
    for bar, d, sign in ((bl, dl, 1.0), (br, dr, -1.0)):
        # the middle of the bar's face from its outer edge (a run may hold another frame's bar beside it)
        f = d / B_over_bar
        c_a, c_b = sorted((bar.outer + sign * 0.25 * f, bar.outer + sign * 0.75 * f))
        cols = np.arange(int(math.floor(c_a)), max(int(math.ceil(c_b)), int(math.floor(c_a)) + 1))
        rc = np.round(cols + 0.5 - disparity(cols + 0.5) - 0.5).astype(int)
        if rc.min() < 0 or cols.max() >= w_img:
            return None
        up_l = _norm(L[1][t0:mid, cols] - colour) < tol
        up_r = _norm(R[1][t0:mid, rc] - colour) < tol
        up = (up_l & up_r)[::-1]  # from the band's middle upwards
        if not np.all(up[0]) or np.any(up.all(axis=0)):
            return None  # not the bar at the middle row, or no end within the window
        tops.append(float(np.mean(mid - np.argmin(up, axis=0))))
        centres.append(float(cols.mean() + 0.5))
    slope = (tops[1] - tops[0]) / (centres[1] - centres[0])
    top = (tops[0] - slope * centres[0], slope)
    ca, cb = int(math.ceil(bl.inner)) + 1, int(math.floor(br.inner)) - 1
    if cb - ca < 3:
        return None
    us = np.arange(ca, cb) + 0.5
    thick = disparity(us) / B_over_bar  # a bar's face in pixels: fx bar / z = d bar / B
    # the top bar runs between the corners: bar-coloured half a bar below the top line
    on_top = np.zeros(len(us), dtype=bool)
    for frac in (0.25, 0.5, 0.75):
        rows_top = np.clip(np.round(top[0] + top[1] * us + frac * thick - 0.5).astype(int), 0, h_img - 1)
        on_top |= _norm(L[1][rows_top, np.arange(ca, cb)] - colour) < tol
    if on_top.mean() < _MIN_COVER:
        return None

    def outside(line: tuple[float, float], depth_share: float) -> float:
        """Share of the rows a bar's thickness in from ``line`` that are bar-coloured just outside the outer edges
        (a frame's top and bottom bars end at its outer edges; a longer one is another frame's)."""
        hits = []
        for u_edge, step in ((bl.outer, -1.0), (br.outer, 1.0)):
            th = float(disparity(np.array([u_edge]))[0]) / B_over_bar
            for off in (2.0, 3.0, 4.0):
                u = u_edge + step * off
                v = line[0] + line[1] * u + depth_share * th
                ui, vi = int(math.floor(u)), int(math.floor(v))
                if 0 <= ui < w_img and 0 <= vi < h_img:
                    hits.append(float(np.linalg.norm(L[1][vi, ui] - colour)) < tol)
        return float(np.mean(hits)) if hits else 1.0

    def meets(line: tuple[float, float], runs: list[list[int]]) -> bool:
        """Whether the bottom bar on ``line`` meets both vertical bars: found on it in a third of the columns a
        bar's thickness next to each (another frame's bar seen between them does not reach them)."""
        n_end = max(3, int(round(float(thick.max()))))
        for sel in (slice(0, n_end), slice(len(us) - n_end, len(us))):
            near = [
                any(abs(e - line[0] - line[1] * u) <= 1.5 for e in ends)
                for u, ends in zip(us[sel], runs[sel], strict=True)
            ]
            if sum(near) < len(near) / 3:
                return False
        return True

    # the bottom bar: each column's bar-coloured runs below the middle as thick as a bar at the frame's disparity
    # (thicker: merged with another frame's bar); the lowest (frames behind stand farther, seen higher) whose line
    # ends at the outer edges, else the next one up
    mask = _norm(L[1][mid:t1, ca:cb] - colour) < tol
    runs = [
        [mid + e_ for s_, e_ in col if e_ < t1 - mid and 0.8 * th - 1.0 <= e_ - s_ <= 1.35 * th + 1.5]
        for th, col in zip(thick, _column_runs(mask), strict=True)
    ]
    for _ in range(3):
        pts = np.array([(u, ends[-1]) for u, ends in zip(us, runs, strict=True) if ends])
        if len(pts) < _MIN_BOTTOM * (cb - ca):
            return (top, None) if partial else None
        bottom = _fit(pts[:, 0], pts[:, 1])
        if bottom is None:
            return (top, None) if partial else None
        on = np.abs(pts[:, 1] - bottom[0] - bottom[1] * pts[:, 0]) <= 1.0
        if on.sum() >= _MIN_BOTTOM * (cb - ca) and outside(bottom, -0.5) <= 0.5 and meets(bottom, runs):
            # on one line over most of the columns (not legs), from bar to bar, ending at the outer edges
            return top, bottom
        line = bottom
        runs = [[e for e in ends if abs(e - line[0] - line[1] * u) > 2.0] for u, ends in zip(us, runs, strict=True)]
    return (top, None) if partial else None


def _square_bottom(
    L: tuple[np.ndarray, np.ndarray],
    R: tuple[np.ndarray, np.ndarray],
    top: tuple[float, float],
    lb: tuple[_Bar, float, float],
    rb: tuple[_Bar, float, float],
    outer_m: float,
    f: float,
    cx: float,
    cy: float,
    up: np.ndarray,
    B_over_bar: float,
) -> tuple[float, float] | None:
    """The bottom line of a square frame (outer height ``outer_m``, its outer width [m]) whose bars are ``lb`` and
    ``rb`` (each with its disparity and depth) and whose top line is ``top``: its bottom corners below the top
    ones by ``outer_m`` along ``up``, projected. None unless both corners are in the image and confirmed: just inside
    each vertical bar, over the bottom bar's rows, bar-coloured in the left image and at the frame's disparity in
    the right one; just outside the outer edges, not (a longer bar is another frame's)."""
    h_img, w_img = L[1].shape[:2]
    (bl, dl, zl), (br, dr, zr) = lb, rb
    colour, tol = 0.5 * (bl.colour + br.colour), min(bl.tol, br.tol)
    corners = []
    for bar, z, d, sign in ((bl, zl, dl, 1.0), (br, zr, dr, -1.0)):
        u = bar.outer
        v = top[0] + top[1] * u
        X = z * np.array([(u - cx) / f, (v - cy) / f, 1.0]) - outer_m * up  # the bottom corner
        if X[2] <= 0.05:
            return None
        ub, vb = cx + f * X[0] / X[2], cy + f * X[1] / X[2]
        th = d / B_over_bar  # a bar's face [px]
        if not (2.0 <= vb - th and vb + 2.0 < h_img):
            return None  # not seen: nothing confirms it
        rows = np.arange(int(math.floor(vb - 0.75 * th)), int(math.ceil(vb - 0.25 * th)))
        cols = np.arange(int(math.floor(ub + sign * 1.5 * th)), int(math.floor(ub + sign * 3.0 * th)), int(sign))
        outside = np.arange(int(math.floor(ub - sign * 2.0)), int(math.floor(ub - sign * 5.0)), -int(sign))
        rc = np.round(cols - d).astype(int)
        if rows.size == 0 or cols.size == 0 or min(cols.min(), rc.min(), outside.min()) < 0:
            return None
        if max(cols.max(), outside.max()) >= w_img:
            return None
        inside_l = _norm(L[1][np.ix_(rows, cols)] - colour) < tol
        inside_r = _norm(R[1][np.ix_(rows, rc)] - colour) < tol
        out_l = _norm(L[1][np.ix_(rows, outside)] - colour) < tol
        if inside_l.mean() < 0.8 or inside_r.mean() < 0.8 or out_l.mean() > 0.5:
            return None
        corners.append((ub, vb))
    (ua, va), (ub_, vb_) = corners
    slope = (vb_ - va) / (ub_ - ua)
    return va - slope * ua, slope

"""A tunnel frame's opening from a rectified stereo pair and its 2-D box in the left image (issue 26, item 4a).

A frame's box (pixel edges, as a detector gives it) has the frame's vertical bars along its left and right
edges. Each bar's disparity is found by matching its strip (the bar and two pixels right of it, over the middle
70 % of the box's rows; the pixels left of a bar are hidden by it in the right image) along the same rows of the
right image
(:func:`~cufund.perception.stereo_depth.box_disparities`: normalised cross-correlation, sub-pixel), over the
disparities a frame of the box's height can have (an opening between ``min_opening`` and ``max_opening``), and
matched back from the right image into the left (a left-right check): the frames' bars are plain and alike, and
a dense matcher confuses one with another. With z = fx B / d, the box's left and right edges at its middle
row become the bars' outer faces in the camera frame, and in the world frame with the body pose given (the
estimate at the image's stamp, never the truth). The frame stands upright: its plane's normal is horizontal,
across the line between the two faces. The box's top and bottom edges (on the nearer bar's column, whose corner
is the box's top) meet the faces' plane at the frame's outer top and bottom, so the opening's size is the outer
size less two bars, and its centre the middle of the four points moved half a bar (the bars' depth) along the
normal.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from cufund.core.config import ConfigError
from cufund.geometry import Transform
from cufund.sensors.camera import R_CO, CameraIntrinsics

from .camera_tunnel_refine import refine_frame_box
from .stereo_depth import _grey, box_disparities

__all__ = ["CameraTunnelParams", "FrameMeasurement", "disparity_span", "frame_from_box", "measure_frame"]


@dataclass(frozen=True)
class CameraTunnelParams:
    """How frames are measured from a stereo pair. Lengths [m], pixels [px]."""

    bar: float = 0.05
    """Thickness and depth of the frames' bars (the competition's rules) [m]."""
    max_disparity: int = 96
    """Largest disparity searched [px] (the nearest frame measured is fx B / max_disparity away)."""
    edge_margin_px: float = 2.0
    """A box within this of the image's border is truncated: not measured [px]."""
    min_box_px: float = 16.0
    """Smallest box side measured [px]."""
    band: float = 0.1
    """Width of the strip matched inside each vertical edge, as a share of the box's width (at least 4 px) [-]."""
    max_range: float = 6.0
    """Frames farther than this are not measured (the depth's noise grows as its square) [m]."""
    max_yaw_deg: float = 60.0
    """A frame measured turned by more than this from the camera's view is taken for a mismatch [deg]."""
    min_opening: float = 0.3
    """Smallest opening width or height measured (the rules' 0.5 m less a margin) [m]. With ``max_opening`` it
    bounds the disparity searched: a box ``h`` px tall is a frame fy (opening + 2 bars) / h away."""
    max_opening: float = 2.0
    """Largest opening width or height measured (the rules' 1.5 m and a margin) [m]."""
    refine: bool = True
    """Refine a detector's box to the frame's bars and top and bottom in the pair before measuring it
    (:mod:`.camera_tunnel_refine`; :func:`measure_frame`). Off: the box's edges are taken as the frame's."""
    refine_max_yaw_deg: float = 40.0
    """A refined pair of bars making a frame turned by more than this from the view is taken for two frames' bars
    (the generated courses turn by at most 15 deg from frame to frame, 30 deg at the entrance) [deg]."""
    partial_min_width: float = 0.9
    """With ``refine``: a frame whose bars and top are found but whose bottom bar is not (merged in the image with
    a nearer frame's bar across it: a big frame seen behind a small one) is measured with the bottom of the rules'
    square opening (openings 1 m wide or more are square) when its opening is at least this wide and that bottom
    is confirmed at both corners in the pair (:attr:`FrameMeasurement.partial`) [m]. 0: never."""
    partial_max_range: float = 2.5
    """Such a frame farther than this is not measured: a pixel of disparity is 14 cm at 2.5 m (fx 400, 11 cm
    baseline), and a frame seen far behind a small one (a 1 m frame 4 m away, 22 cm off) has no bottom bar to check
    its depth by [m]."""

    def __post_init__(self) -> None:
        for name in (
            "bar",
            "edge_margin_px",
            "min_box_px",
            "band",
            "max_range",
            "max_yaw_deg",
            "min_opening",
            "refine_max_yaw_deg",
            "partial_min_width",
            "partial_max_range",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"perception.{name} must be a finite number >= 0, got {v!r}")
        if not 0.0 < self.band <= 0.5:
            raise ConfigError(f"perception.band must be in (0, 0.5] (a share of the box's width), got {self.band!r}")
        if not self.min_opening < self.max_opening <= 100.0 or self.max_yaw_deg >= 90.0:
            raise ConfigError(
                f"perception: need min_opening < max_opening <= 100 m and max_yaw_deg < 90, got {self.min_opening}, "
                f"{self.max_opening}, {self.max_yaw_deg}"
            )
        if self.bar <= 0 or self.max_range <= 0:
            raise ConfigError(
                f"perception.bar and perception.max_range must be > 0 [m], got {self.bar}, {self.max_range}"
            )
        if not isinstance(self.refine, bool):
            raise ConfigError(f"perception.refine must be true or false, got {self.refine!r}")
        v = self.max_disparity
        if isinstance(v, bool) or not isinstance(v, int) or not 2 <= v <= 4096:
            raise ConfigError(f"perception.max_disparity must be an integer in [2, 4096] [px], got {v!r}")


@dataclass(frozen=True)
class FrameMeasurement:
    """One frame measured in one stereo pair, in the world frame of the pose given."""

    centre_W: np.ndarray
    """(3,) the opening's centre [m]."""
    normal_W: np.ndarray
    """(3,) unit horizontal normal of the frame's plane, pointing away from the camera [-]."""
    width: float
    """Opening width [m]."""
    height: float
    """Opening height [m]."""
    depth: float
    """Mean distance of the two bars from the camera along its optical axis [m]."""
    points_W: np.ndarray
    """(4, 3) the frame's outer left, right, top and bottom points found [m]."""
    partial: bool = False
    """The bottom bar was not found; the bottom is the rules' square opening's, confirmed at its corners
    (:attr:`CameraTunnelParams.partial_min_width`)."""


_LR_TOLERANCE_PX = 1.0
"""Largest difference between a strip's disparity and its match's matched back [px]."""
_STRIP_PAD_PX = 1.5
"""How far outside a refined box's vertical edges (the bars' exact outer edges) the bar strips start [px]: the
strips are matched by the edges' contrast. Over six approaches (paper layout, generated seeds 0, 1, 3, 4, 7) with
the shipped model's boxes, tracked: the strips alone (from 0 px) 4.5 cm and 4.5 deg, (from 1.5 px) 1.2 cm and
2.0 deg; the outer edges' disparities alone 1.1 cm and 1.5 deg (3.6 deg on seed 7); their mean 1.1 cm and 1.5 deg
(at most 1.7 cm and 3.7 deg, seed 3)."""
_AGREE_PX = 1.0
"""Largest difference between a refined bar's disparity from its outer edges and from its strip [px]."""
_RIGHT_PX = 2.0
"""Pixels right of each bar in its strip (the bar's right edge; what lies just left of a bar in the left image is
hidden by it in the right image, so no pixel left of a bar is matched)."""


def _bar_strips(box: tuple[float, float, float, float], band_px: tuple[float, float]) -> np.ndarray:
    """Boxes whose middle halves (what :func:`~.stereo_depth.box_disparities` matches) are the strips of the box's
    left and right bars: ``band_px`` (left, right) wide inside the box's edge and ``_RIGHT_PX`` right of the bar,
    over the middle 70 % of the box's rows."""
    u0, v0, u1, v1 = box
    cv, hh = 0.5 * (v0 + v1), 0.35 * (v1 - v0)
    out = []
    for a, b in ((u0, u0 + band_px[0] + _RIGHT_PX), (u1 - band_px[1], u1 + _RIGHT_PX)):
        cu, hw = 0.5 * (a + b), 0.5 * (b - a)
        out.append((cu - 2 * hw, cv - 2 * hh, cu + 2 * hw, cv + 2 * hh))
    return np.array(out)


def _match(
    left: np.ndarray, right: np.ndarray, strips: np.ndarray, span: tuple[float, float], check: bool = True
) -> tuple[float, float] | None:
    """The disparities of the two strips searched over ``span`` (min, max) [px] only: the right image shifted by
    the least disparity, :func:`~.stereo_depth.box_disparities` over the rest. None if either finds no match
    (also at an end of the span)."""
    lo, hi = max(int(math.floor(span[0])) - 2, 0), int(math.ceil(span[1])) + 2  # a peak at an end is refused
    if hi - lo < 2:
        return None
    shifted = np.zeros_like(np.asarray(right))
    shifted[:, lo:] = np.asarray(right)[:, : shifted.shape[1] - lo]  # disparity d in right is d - lo in shifted
    disp, ok = box_disparities(left, shifted, strips, hi - lo)
    if not np.all(ok):
        return None
    d = disp + lo
    if not check:
        return float(d[0]), float(d[1])
    # left-right check: each strip's match in the right image, matched back into the left one (both mirrored, so
    # the right image is the left of the pair), must come back to the strip (plain bars repeat)
    w = np.asarray(left).shape[1]
    back = np.stack([w - (strips[:, 2] - d), strips[:, 1], w - (strips[:, 0] - d), strips[:, 3]], axis=1)
    rev, ok = box_disparities(np.asarray(right)[:, ::-1], np.asarray(left)[:, ::-1], back, hi + 2)
    if check and (not np.all(ok) or np.any(np.abs(rev - d) > _LR_TOLERANCE_PX)):
        return None
    return float(d[0]), float(d[1])


def _strip_disparities(
    box: tuple[float, float, float, float],
    left: np.ndarray,
    right: np.ndarray,
    baseline: float,
    span: tuple[float, float],
    p: CameraTunnelParams,
) -> tuple[float, float] | None:
    """The two bars' disparities [px] from their strips matched in the right image (the module's first step), or
    None; ``left``, ``right`` grey."""
    u0, v0, u1, v1 = box
    band = max(4.0, p.band * (u1 - u0))
    disp = _match(left, right, _bar_strips(box, (band, band)), span, check=False)  # coarse
    if disp is None:
        return None
    # again on the bars alone (their width in pixels at the depth found, fx bar / z = d bar / B): what is seen
    # through the opening, farther, no longer pulls the match; checked left-right
    bars = (max(3.0, disp[0] * p.bar / baseline), max(3.0, disp[1] * p.bar / baseline))
    return _match(left, right, _bar_strips(box, bars), span)


def disparity_span(
    height_px: float, K: CameraIntrinsics, baseline: float, p: CameraTunnelParams
) -> tuple[float, float]:
    """The disparities [px] a frame ``height_px`` tall in the image can have: its outer height is 2 bars more than
    an opening in [min_opening, max_opening], so its disparity lies in B height_px / outer height (plain bars
    repeat: elsewhere they match as well)."""
    return (
        baseline * height_px * K.fx / K.fy / (p.max_opening + 2 * p.bar),
        min(baseline * height_px * K.fx / K.fy / (p.min_opening + 2 * p.bar), float(p.max_disparity)),
    )


def measure_frame(
    box_xyxy: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    K: CameraIntrinsics,
    baseline: float,
    T_BC: Transform,
    p_WB: np.ndarray,
    R_WB: np.ndarray,
    params: CameraTunnelParams | None = None,
) -> FrameMeasurement | None:
    """:func:`frame_from_box` on a detector's box refined to the frame's own edges first
    (:func:`~.camera_tunnel_refine.refine_frame_box`, with ``params.refine``): a detector's box edges are off by
    several pixels, the bar strips need them within one or two. The bars' disparities are found from their outer
    edges in both images and from their strips; both must agree (see below). None when the refinement finds no
    frame, the two disparities disagree, or the measurement refuses it."""
    p = CameraTunnelParams() if params is None else params
    box = np.asarray(box_xyxy, dtype=float).reshape(4)
    if p.refine:
        if not np.all(np.isfinite(box)) or box[3] - box[1] < p.min_box_px:
            return None
        lo, hi = disparity_span(box[3] - box[1], K, baseline, p)
        # the box's height is off too: the span widened by the margin searched around its edges
        span = (0.7 * lo, min(1.3 * hi, float(p.max_disparity)))
        up_O = (np.asarray(R_WB, dtype=float) @ T_BC.R @ R_CO).T @ np.array([0.0, 0.0, 1.0])  # from the estimate
        refined = refine_frame_box(
            box,
            left,
            right,
            baseline,
            p.bar,
            span,
            K.fx,
            K.cx,
            K.cy,
            up_O,
            max_yaw_deg=p.refine_max_yaw_deg,
            partial_min_width=p.partial_min_width,
        )
        if refined is None:
            return None
        # the bars' disparities from their outer edges in both images and from their strips (started outside the
        # edges, so that the edges' contrast is in them): where both are found they must agree, and are averaged.
        # Where the strips fail their left-right check (plain bars seen nested or merged), the edges' alone, if
        # the right image's runs are each one bar wide at their disparity (a run of several frames' bars merged
        # may have its outer edge matched to another run's: frames measured 1 m too far so in a flight).
        box = np.array(refined.box_xyxy)
        padded = (box[0] - _STRIP_PAD_PX, box[1], box[2] + _STRIP_PAD_PX, box[3])
        span = disparity_span(box[3] - box[1], K, baseline, p)
        strips = _strip_disparities(padded, _grey(left), _grey(right), baseline, span, p)
        edges = refined.disparities
        if strips is None:
            if not refined.single:
                return None
            disp = edges
        elif max(abs(strips[0] - edges[0]), abs(strips[1] - edges[1])) > _AGREE_PX:
            return None
        else:
            disp = (0.5 * (edges[0] + strips[0]), 0.5 * (edges[1] + strips[1]))
        m = frame_from_box(box, left, right, K, baseline, T_BC, p_WB, R_WB, p, disparities=disp)
        if m is None or not refined.partial:
            return m
        if m.width < p.partial_min_width or m.depth > p.partial_max_range:  # (the strips' disparities too)
            return None
        return dataclasses.replace(m, partial=True)
    return frame_from_box(box, left, right, K, baseline, T_BC, p_WB, R_WB, p)


def frame_from_box(
    box_xyxy: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    K: CameraIntrinsics,
    baseline: float,
    T_BC: Transform,
    p_WB: np.ndarray,
    R_WB: np.ndarray,
    params: CameraTunnelParams | None = None,
    disparities: tuple[float, float] | None = None,
) -> FrameMeasurement | None:
    """The frame in the box ``box_xyxy`` (u_min, v_min, u_max, v_max pixel edges of the ``left`` image) from the
    rectified pair (``left``, ``right``), the left camera ``K`` mounted at ``T_BC`` (the right one ``baseline``
    [m] to its right), the body at ``p_WB``, ``R_WB``. None when the box is truncated by the image's border, too
    small, too far, seen edge-on, or either bar's strip finds no match in the right image. ``disparities``: the left and right bars' disparities [px] found already (no strip matched then)."""
    p = CameraTunnelParams() if params is None else params
    h, w = np.asarray(left).shape[:2]
    u0, v0, u1, v1 = (float(x) for x in np.asarray(box_xyxy, dtype=float).reshape(4))
    m = p.edge_margin_px
    if not all(math.isfinite(x) for x in (u0, v0, u1, v1)):
        return None
    if u0 < m or v0 < m or u1 > w - m or v1 > h - m or min(u1 - u0, v1 - v0) < p.min_box_px:
        return None
    if disparities is None:
        span = disparity_span(v1 - v0, K, baseline, p)
        # the pair turned grey once: each of the three strip matches would convert a colour pair
        disp = _strip_disparities((u0, v0, u1, v1), _grey(left), _grey(right), baseline, span, p)
        if disp is None:
            return None
    else:
        disp = (float(disparities[0]), float(disparities[1]))
        if not all(math.isfinite(d) and d > 0 for d in disp):
            return None
    z_left, z_right = (K.fx * baseline / float(d) for d in disp)
    depth = 0.5 * (z_left + z_right)
    if depth > p.max_range:
        return None
    R_WO = R_WB @ T_BC.R @ R_CO
    o_W = np.asarray(p_WB, dtype=float) + R_WB @ np.asarray(T_BC.t, dtype=float)

    def ray(u: float, v: float) -> np.ndarray:
        return R_WO @ np.array([(u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0])  # z = 1 along the optical axis

    vm = 0.5 * (v0 + v1)
    e_left, e_right = o_W + z_left * ray(u0, vm), o_W + z_right * ray(u1, vm)  # the bars' outer faces
    across = e_right - e_left
    across[2] = 0.0
    if np.linalg.norm(across) < 1e-6:
        return None
    across /= np.linalg.norm(across)
    n = np.array([across[1], -across[0], 0.0])  # horizontal, across the line left bar -> right bar
    view = R_WO[:, 2].copy()
    view[2] = 0.0
    if float(n @ view) < 0:
        n = -n
    offset = 0.5 * float((e_left + e_right) @ n)  # the plane of the bars' faces (the box's edges are theirs)

    def on_plane(u: float, v: float) -> np.ndarray | None:
        r = ray(u, v)
        if float(r @ n) <= 0.05 * float(np.linalg.norm(r)):  # seen edge-on
            return None
        return o_W + (offset - float(o_W @ n)) / float(r @ n) * r

    u_near = u0 if z_left <= z_right else u1  # the nearer side's corner is the box's top (and bottom) edge
    corners = [on_plane(u0, vm), on_plane(u1, vm), on_plane(u_near, v0), on_plane(u_near, v1)]
    if any(c is None for c in corners):
        return None
    el, er, top, bottom = (np.asarray(c) for c in corners)
    if (
        float(np.degrees(np.arccos(min(1.0, abs(float(n @ view)) / max(float(np.linalg.norm(view)), 1e-12)))))
        > p.max_yaw_deg
    ):
        return None  # the two bars' depths disagree more than a frame turned by max_yaw_deg: a mismatch
    centre = 0.5 * (el + er) + 0.5 * p.bar * n  # the frame's plane: half a bar behind its faces
    centre[2] = 0.5 * (top[2] + bottom[2])
    width, height = float(np.linalg.norm((er - el)[:2])) - 2 * p.bar, float(top[2] - bottom[2]) - 2 * p.bar
    if not (p.min_opening <= width <= p.max_opening and p.min_opening <= height <= p.max_opening):
        return None
    return FrameMeasurement(
        centre_W=centre,
        normal_W=n,
        width=width,
        height=height,
        depth=depth,
        points_W=np.stack([el, er, top, bottom]),
    )

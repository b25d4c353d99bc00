"""A run's figures, each as a 200 dpi PNG and an SVG: ``trajectory`` (top and side views scaled to the flight,
with the world's footprint, waypoints and gates; truth, estimate, setpoints; for a course with a centre line, the
lateral deviation from it on an exaggerated scale) and ``errors`` (tracking and odometry error over time, the
mission's phases as bands)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .flight import Flight, Phase

__all__ = ["DPI", "centreline_coordinates", "plot_errors", "plot_trajectory", "pyplot", "save_figure"]

DPI = 200
TRUTH, ESTIMATE, SETPOINT = "#d62728", "#1f77b4", "#2ca02c"
"""Truth red, estimate blue, setpoints green (as the replay; the paper's Fig. 8)."""
GROUND_LABELS = ("floor", "ground", "ceiling")
"""World objects left out of the top view (they cover it)."""
PHASE_COLOURS = ("#fde0c5", "#d5e8f6", "#dcefd0", "#ecdff2", "#fbf2c0", "#e3e3e3", "#f6d5d5", "#d3f0ee")


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (files, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, stem: str | Path, dpi: int = DPI) -> list[Path]:
    """Saves ``fig`` as ``stem``.png (``dpi``) and ``stem``.svg, closes it; returns both paths."""
    stem = Path(stem)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".svg")]
    fig.savefig(paths[0], dpi=dpi)
    fig.savefig(paths[1])
    pyplot().close(fig)
    return paths


def centreline_coordinates(points_W: np.ndarray, line_W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance along the polyline ``line_W`` (M, 3) and signed horizontal offset from it (positive: left of
    the direction of travel) of each of ``points_W`` (N, 3), both [m], from the nearest segment (the first and
    last segments extended beyond their ends)."""
    pts = np.asarray(points_W, dtype=float).reshape(-1, 3)[:, :2]
    line = np.asarray(line_W, dtype=float).reshape(-1, 3)[:, :2]
    a, b = line[:-1], line[1:]
    seg = b - a
    length = np.linalg.norm(seg, axis=1)
    keep = length > 1e-9
    a, seg, length = a[keep], seg[keep], length[keep]
    if len(a) == 0:
        raise ValueError("the centre line needs two distinct points")
    s0 = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    u = seg / length[:, None]
    rel = pts[:, None, :] - a[None, :, :]  # (N, S, 2)
    along = np.einsum("nsk,sk->ns", rel, u)
    lo = np.where(np.arange(len(a)) == 0, -np.inf, 0.0)
    hi = np.where(np.arange(len(a)) == len(a) - 1, np.inf, length)
    clamped = np.clip(along, lo, hi)
    closest = a[None] + clamped[..., None] * u[None]
    dist = np.linalg.norm(pts[:, None, :] - closest, axis=2)
    k = np.argmin(dist, axis=1)
    n = np.arange(len(pts))
    cross = u[k, 0] * rel[n, k, 1] - u[k, 1] * rel[n, k, 0]
    return s0[k] + clamped[n, k], cross


def _footprints(ax: Any, world: Any, lo: np.ndarray, hi: np.ndarray) -> None:
    """The world's objects seen from above (convex hull of each), those that reach into the view."""
    from matplotlib.patches import Polygon
    from scipy.spatial import ConvexHull, QhullError

    first = True
    for obj in world.objects:
        if obj.label in GROUND_LABELS:
            continue
        v = np.asarray(obj.vertices, dtype=float)[:, :2]
        vmin, vmax = v.min(axis=0), v.max(axis=0)
        if np.any(vmax < lo) or np.any(vmin > hi):
            continue
        try:
            hull = v[ConvexHull(v).vertices]
        except (QhullError, ValueError):
            continue
        colour = tuple(0.55 + 0.45 * np.asarray(obj.color)) if obj.label == "wall" else tuple(obj.color)
        ax.add_patch(
            Polygon(
                hull,
                closed=True,
                fc=colour,
                ec="0.3",
                lw=0.3,
                alpha=0.7,
                zorder=1,
                label=None if not first else "world (footprints)",
            )
        )
        first = False


def _limits(points: np.ndarray, margin: float, minimum: float) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = points.min(axis=0), points.max(axis=0)
    pad = np.maximum(margin * (hi - lo), minimum)
    return lo - pad, hi + pad


def _gate_ends(centre: np.ndarray, normal: np.ndarray, half: float) -> np.ndarray:
    a = np.array([normal[0], normal[1]]) / max(float(np.hypot(normal[0], normal[1])), 1e-12)
    across = np.array([-a[1], a[0]])
    return np.array([centre[:2] - half * across, centre[:2] + half * across])


def plot_trajectory(stem: str | Path, flight: Flight, world: Any = None) -> list[Path]:
    """``stem``.png/.svg: top view (x-y, equal scale, framed on the flight) with the world's footprint, the
    waypoints and the gates; side view (height against the distance along the course, or along x or y);
    with a centre line, a third panel: the lateral offset from it [cm] on its own, exaggerated, scale."""
    plt = pyplot()
    f = flight
    curves: list[tuple[np.ndarray, str, str, float, str]] = [
        (np.asarray(p).reshape(-1, 3)[:: max(1, len(p) // 6000)], colour, ls, lw, label)
        for p, colour, ls, lw, label in (
            (f.p_sp_W, SETPOINT, "-", 1.3, "setpoint"),
            (f.p_est_W, ESTIMATE, "-", 1.0, "estimate (odometry)"),
            (f.p_W, TRUTH, "--", 1.0, "truth"),
        )
        if len(p)
    ]
    line = np.zeros((0, 3)) if f.centreline_W is None else np.asarray(f.centreline_W, dtype=float).reshape(-1, 3)
    deviation = len(line) >= 2
    fig = plt.figure(figsize=(13, 9.5 if deviation else 5.6), layout="constrained")
    gs = fig.add_gridspec(
        2 if deviation else 1, 2, width_ratios=[1.35, 1], height_ratios=[1.25, 1] if deviation else [1]
    )
    top, side = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[0, 1])
    pts = f.framing_points()
    lo, hi = _limits(pts, 0.08, 0.3)
    if world is not None:  # the equal scale widens the shorter axis: take the objects of a square about the flight
        half = 1.6 * float(np.max(hi[:2] - lo[:2])) / 2.0
        _footprints(top, world, (lo[:2] + hi[:2]) / 2.0 - half, (lo[:2] + hi[:2]) / 2.0 + half)
    if f.planned_is_reference and len(f.planned_W):
        top.plot(f.planned_W[:, 0], f.planned_W[:, 1], ":", color="0.35", lw=1.0, label="planned", zorder=2)
    for p, colour, ls, lw, label in curves:
        top.plot(p[:, 0], p[:, 1], ls, color=colour, lw=lw, label=label, zorder=3)
    true_gates = [g for g in f.gates if not g.detected]
    found_gates = [g for g in f.gates if g.detected]
    for k, g in enumerate(true_gates):
        e = _gate_ends(g.centre_W, g.normal_W, g.width / 2 + 0.05)
        top.plot(
            e[:, 0],
            e[:, 1],
            color="k",
            lw=3,
            solid_capstyle="butt",
            zorder=4,
            label="gates (truth)" if k == 0 else None,
        )
        top.annotate(str(k + 1), g.centre_W[:2], xytext=(0, 9), textcoords="offset points", ha="center", fontsize=8)
    for k, g in enumerate(found_gates):
        e = _gate_ends(g.centre_W, g.normal_W, g.width / 2)
        top.plot(
            e[:, 0], e[:, 1], color="tab:orange", lw=1.5, ls=":", zorder=5, label="gates (detected)" if k == 0 else None
        )
    if len(f.waypoints_W):
        w = f.waypoints_W
        top.plot(w[:, 0], w[:, 1], "o", mfc="none", mec="k", ms=8, zorder=5, label=f.waypoints_label)
        numbers: dict[tuple[float, float], list[str]] = {}  # a closed path's last waypoint is its first
        for k, xy in enumerate(w[:, :2]):
            numbers.setdefault((round(float(xy[0]), 3), round(float(xy[1]), 3)), []).append(str(k + 1))
        for xy, names in numbers.items():
            top.annotate(", ".join(names), xy, xytext=(6, 6), textcoords="offset points", fontsize=8)
    top.plot(*f.p_W[0, :2], "^", color="k", ms=7, zorder=6, label="start")
    top.plot(*f.p_W[-1, :2], "s", color="k", ms=6, zorder=6, label="end")
    top.ignore_existing_data_limits = True  # framed on the flight, not on the world's footprints
    top.update_datalim(np.array([lo[:2], hi[:2]]))
    top.autoscale_view(tight=True)
    top.set_aspect("equal", adjustable="datalim")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("top view")
    top.grid(True, alpha=0.3)

    # side view: height against the distance along the course (centre line), else along the longer axis
    if deviation:

        def along(p: np.ndarray) -> np.ndarray:
            return centreline_coordinates(p, line)[0]

        xlabel = "distance along the course centre line [m]"
    else:
        axis = 0 if (hi - lo)[0] >= (hi - lo)[1] else 1

        def along(p: np.ndarray) -> np.ndarray:
            return np.asarray(p)[:, axis]

        xlabel = f"{'xy'[axis]} [m]"
    for p, colour, ls, lw, label in curves:
        side.plot(along(p), p[:, 2], ls, color=colour, lw=lw, label=label)
    for k, g in enumerate(true_gates):
        s = along(g.centre_W.reshape(1, 3))[0]
        side.plot(
            [s, s],
            [g.centre_W[2] - g.height / 2, g.centre_W[2] + g.height / 2],
            color="k",
            lw=3,
            solid_capstyle="butt",
            label="gates (truth)" if k == 0 else None,
        )
    if len(f.waypoints_W):
        side.plot(along(f.waypoints_W), f.waypoints_W[:, 2], "o", mfc="none", mec="k", ms=8, label=f.waypoints_label)
    side.set_xlabel(xlabel)
    side.set_ylabel("z [m]")
    side.set_ylim(min(-0.05, lo[2]), hi[2] + 0.1)
    side.set_title("side view")
    side.grid(True, alpha=0.3)

    if deviation:
        dev = fig.add_subplot(gs[1, :])
        gates_s = [centreline_coordinates(g.centre_W.reshape(1, 3), line)[0][0] for g in true_gates]
        window = (min(gates_s) - 0.5, max(gates_s) + 0.5) if gates_s else None
        extent = 0.02
        for p, colour, ls, lw, label in curves:
            s, d = centreline_coordinates(p, line)
            dev.plot(s, 100 * d, ls, color=colour, lw=lw, label=label)
            inside = (s >= window[0]) & (s <= window[1]) if window else np.ones(len(s), bool)
            if inside.any():
                extent = max(extent, float(np.abs(d[inside]).max()))
        for k, s in enumerate(gates_s):
            dev.axvline(s, color="k", lw=1.5, ls="-", alpha=0.6)
            dev.annotate(
                f"gate {k + 1}",
                (s, 1),
                xycoords=("data", "axes fraction"),
                xytext=(3, -12),
                textcoords="offset points",
                fontsize=8,
            )
        dev.axhline(0.0, color="0.3", lw=0.8)
        dev.set_ylim(-130 * extent, 130 * extent)
        if window:
            dev.set_xlim(window[0] - 1.0, window[1] + 1.0)
        dev.set_xlabel("distance along the course centre line [m]")
        dev.set_ylabel("lateral offset [cm]")
        dev.set_title(
            "lateral offset from the course centre line (through the true gate centres), exaggerated scale: "
            "y in cm, x in m",
            fontsize=10,
        )
        dev.grid(True, alpha=0.3)
    if f.title:
        fig.suptitle(f.title, fontsize=11)
    # one legend for the figure, under it: it hides nothing
    entries: dict[str, Any] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    fig.legend(entries.values(), entries.keys(), loc="outside lower center", ncol=min(len(entries), 8), fontsize=8)
    return save_figure(fig, stem)


def _interp_rows(t_query: np.ndarray, t: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t_query, t, p[:, k]) for k in range(p.shape[1])])


def _bands(ax: Any, phases: list[Phase], t0: float, t1: float, strip: Any = None) -> list[Any]:
    """Shades each phase on ``ax``; in ``strip`` (a thin axes above) each band with its name when it fits.
    Returns legend handles (one per phase name)."""
    from matplotlib.patches import Patch

    colours: dict[str, str] = {}
    span = max(t1 - t0, 1e-9)
    for ph in phases:
        colour = colours.setdefault(ph.name, PHASE_COLOURS[len(colours) % len(PHASE_COLOURS)])
        ax.axvspan(ph.t0, ph.t1, color=colour, lw=0, zorder=0)
        if strip is not None:
            strip.axvspan(ph.t0, ph.t1, color=colour, lw=0)
            strip.axvline(ph.t0, color="0.5", lw=0.5)
            if (ph.t1 - ph.t0) / span > 0.0075 * len(ph.name) + 0.01:
                strip.text((ph.t0 + ph.t1) / 2, 0.5, ph.name, ha="center", va="center", fontsize=8, clip_on=True)
    return [Patch(color=c, label=n) for n, c in colours.items()]


def plot_errors(stem: str | Path, flight: Flight) -> list[Path]:
    """``stem``.png/.svg: the tracking error |truth - setpoint| and the odometry error |estimate - truth| [cm]
    over time (truth interpolated at each setpoint's and estimate's stamp), the phases as bands (named in a strip
    above when a name fits, all in the legend)."""
    plt = pyplot()
    f = flight
    panels = []
    if len(f.t_sp):
        inside = (f.t_sp >= f.t[0]) & (f.t_sp <= f.t[-1])
        ts = f.t_sp[inside]
        panels.append(
            (
                ts,
                np.linalg.norm(_interp_rows(ts, f.t, f.p_W) - f.p_sp_W[inside], axis=1),
                SETPOINT,
                "tracking error |truth - setpoint|",
            )
        )
    if len(f.t_est):
        inside = (f.t_est >= f.t[0]) & (f.t_est <= f.t[-1])
        te = f.t_est[inside]
        panels.append(
            (
                te,
                np.linalg.norm(f.p_est_W[inside] - _interp_rows(te, f.t, f.p_W), axis=1),
                ESTIMATE,
                "odometry error |estimate - truth|",
            )
        )
    n = max(1, len(panels))
    fig = plt.figure(figsize=(12, 1.0 + 2.6 * n), layout="constrained")
    gs = fig.add_gridspec(n + 1, 1, height_ratios=[0.22] + [1] * n)
    strip = fig.add_subplot(gs[0])
    axes = [fig.add_subplot(gs[k + 1], sharex=strip) for k in range(n)]
    t0, t1 = float(f.t[0]), float(f.t[-1])
    handles: list[Any] = []
    for k, ax in enumerate(axes):
        handles = _bands(ax, f.phases, t0, t1, strip if k == 0 else None)
    strip.set_yticks([])
    strip.set_ylim(0, 1)
    strip.tick_params(labelbottom=False)
    strip.set_title(f.phases_title if f.phases else "", fontsize=9, loc="left")
    for ax, (t, e, colour, label) in zip(axes, panels, strict=False):
        rmse, mx = float(np.sqrt(np.mean(e**2))), float(e.max())
        ax.plot(
            t,
            100 * e,
            color=colour,
            lw=1.0,
            label=f"{label}: RMSE {100 * rmse:.2f} cm, max {100 * mx:.2f} cm over the plot",
        )
        ax.set_ylabel("error [cm]")
        ax.set_ylim(0, 105 * mx if mx > 0 else 1)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    if not panels:
        axes[0].text(
            0.5, 0.5, "no setpoints or estimate recorded", ha="center", va="center", transform=axes[0].transAxes
        )
    if handles:
        fig.legend(handles=handles, loc="outside right upper", fontsize=8, title="phase", title_fontsize=8)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(t0, t1)
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    if f.title:
        fig.suptitle(f.title, fontsize=11)
    return save_figure(fig, stem)

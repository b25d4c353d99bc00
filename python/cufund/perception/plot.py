"""A figure in the style of the paper's Fig. 9: the cloud, each detected frame's points coloured, centres marked."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .detection import FrameDetection

__all__ = ["plot_detection"]


def plot_detection(
    points_W: object,
    detections: list[FrameDetection],
    truth: object = None,
    path: str | Path | None = None,
    max_points: int = 60_000,
) -> object:
    """Top view (x-y) and side view (distance along the course - z) of ``points_W`` (N, 3) in grey, each
    detection's points in its own colour, its opening's centre (red dot, the paper's marker), the opening's
    edges and normal, the paper's cluster mean (black x) and, if given, the true centres ``truth`` (K, 3) (green
    +); the frames' legend is in the top view, the markers' in the side view. Saves (200 dpi) to ``path`` when given; returns the matplotlib figure."""
    import matplotlib

    if path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    pts = np.asarray(points_W, dtype=float).reshape(-1, 3)
    if len(pts) > max_points:  # an even, deterministic thinning keeps the figure light
        pts = pts[np.linspace(0, len(pts) - 1, max_points).astype(int)]
    true = None if truth is None else np.asarray(truth, dtype=float).reshape(-1, 3)
    centres = np.array([d.centre_W for d in detections]).reshape(-1, 3)
    # the side view unrolls the course: distance along the polyline through the centres
    if len(centres) >= 2:
        direction = centres[-1] - centres[0]
    elif len(centres) == 1:
        direction = detections[0].normal_W
    else:
        direction = np.array([1.0, 0.0, 0.0])
    direction = np.array([direction[0], direction[1], 0.0])
    direction /= max(np.linalg.norm(direction), 1e-9)

    fig, (top, side) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [1.2, 1]})
    above = pts[pts[:, 2] > 0.1]  # the floor would grey the whole top view
    top.scatter(above[:, 0], above[:, 1], s=0.3, c="0.75", lw=0, rasterized=True)
    side.scatter(pts @ direction, pts[:, 2], s=0.3, c="0.75", lw=0, rasterized=True)
    colours = plt.get_cmap("tab10")
    for k, d in enumerate(detections):
        col = colours(k % 10)
        q = d.points_W
        top.scatter(q[:, 0], q[:, 1], s=2, color=col, lw=0, label=f"frame {k + 1}: {d.width:.2f} x {d.height:.2f} m")
        side.scatter(q @ direction, q[:, 2], s=2, color=col, lw=0)
        u = np.array([-d.normal_W[1], d.normal_W[0], 0.0])
        ends = d.centre_W + np.outer([-0.5, 0.5], u * d.width)
        top.plot(ends[:, 0], ends[:, 1], "-", color=col, lw=1.5)
        arrow = d.centre_W + 0.3 * d.normal_W
        top.annotate("", xy=arrow[:2], xytext=d.centre_W[:2], arrowprops={"arrowstyle": "->", "color": col})
        s = d.centre_W @ direction
        side.plot([s, s], [d.centre_W[2] - d.height / 2, d.centre_W[2] + d.height / 2], "-", color=col, lw=1.5)
        for ax, xy in ((top, d.cluster_mean_W[:2]), (side, (d.cluster_mean_W @ direction, d.cluster_mean_W[2]))):
            ax.plot(*xy, "x", color="k", ms=6, mew=1.5, label="cluster mean (paper)" if k == 0 and ax is top else None)
    if len(centres):
        top.plot(centres[:, 0], centres[:, 1], "o", color="red", ms=5, label="detected centre")
        side.plot(centres @ direction, centres[:, 2], "o", color="red", ms=5)
    if true is not None and len(true):
        top.plot(true[:, 0], true[:, 1], "+", color="green", ms=12, mew=1.5, label="true centre")
        side.plot(true @ direction, true[:, 2], "+", color="green", ms=12, mew=1.5)
    span = np.vstack([c for c in (centres, true) if c is not None and len(c)] or [np.zeros((1, 3))])
    lo, hi = span.min(axis=0) - 1.5, span.max(axis=0) + 1.5
    top.set_xlim(lo[0], hi[0])
    top.set_ylim(lo[1], hi[1])
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("top view")
    # two legends: the frames (their points' colours) in the top view, the markers in the side view
    frames = [h for h in top.collections if not h.get_label().startswith("_")]
    markers = [h for h in top.get_lines() if not h.get_label().startswith("_")]
    if frames:
        top.legend(
            handles=frames, loc="upper left", fontsize=7, markerscale=3, title="detected frames", title_fontsize=7
        )
    along = span @ direction
    side.set_xlim(along.min() - 1.5, along.max() + 1.5)
    side.set_ylim(-0.1, max(2.0, hi[2] - 0.5))
    side.set_aspect("equal")
    side.set_xlabel("along the course [m]")
    side.set_ylabel("z [m]")
    side.set_title("side view")
    if markers:
        side.legend(handles=markers, loc="upper right", fontsize=7, title="markers", title_fontsize=7)
    fig.suptitle("Tunnel frames: DBSCAN clusters, opening centres (red), cluster means (x)")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=200)
        plt.close(fig)
    return fig

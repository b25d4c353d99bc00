"""Matplotlib figures of a run (like the paper's Figs. 5 and 6)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cufund.planning.trajectory import Trajectory
from cufund.simulator import SimulationResult

__all__ = ["plot_tracking"]


def plot_tracking(
    path: str | Path,
    result: SimulationResult,
    reference: Trajectory,
    window: tuple[float, float] | None = None,
    title: str = "",
) -> Path:
    """Saves a PNG: planned vs flown path in 3D (left) and per-axis position tracking over time (right), with
    the tracking-error window shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, p = result.states["t"], result.states["p_W"]
    ref = reference.sample(t).p_W
    fig = plt.figure(figsize=(13, 6), constrained_layout=True)
    gs = fig.add_gridspec(4, 2, width_ratios=[1.1, 1])
    ax3 = fig.add_subplot(gs[:, 0], projection="3d")
    ax3.plot(*ref.T, "--", color="tab:blue", label="planned")
    ax3.plot(*p.T, color="tab:red", lw=1, label="flown")
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.legend(loc="upper left")
    ax3.set_title(title or "planned vs flown path")
    for k, name in enumerate("xyz"):
        ax = fig.add_subplot(gs[k, 1])
        ax.plot(t, ref[:, k], "--", color="tab:blue", label="planned")
        ax.plot(t, p[:, k], color="tab:red", lw=1, label="flown")
        ax.set_ylabel(f"{name} [m]")
        if window is not None:
            ax.axvspan(*window, color="0.9", zorder=0)
        if k == 0:
            ax.legend(loc="upper right", fontsize=8)
        ax.tick_params(labelbottom=False)
    ax = fig.add_subplot(gs[3, 1])
    err = np.linalg.norm(p - ref, axis=1)
    ax.plot(t, 100 * err, color="k", lw=1)
    if window is not None:
        ax.axvspan(*window, color="0.9", zorder=0, label="min-snap segment")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_ylabel("error [cm]")
    ax.set_xlabel("t [s]")
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

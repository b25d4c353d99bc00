"""The tunnel run's files: ``trajectory.png`` (paper Fig. 8: true pose red, odometry blue, setpoints green; top view
with the frames), ``detection.png`` (the detector's Fig.-9-style plot) and ``replay.html`` (the world, the frames,
snapshots of the point cloud and the three paths)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.messages import Topics

from .tunnel_metrics import true_frames

__all__ = ["plot_tunnel_trajectory", "write_tunnel_outputs", "write_tunnel_replay"]

_RED, _BLUE, _GREEN = "#d62728", "#1f77b4", "#2ca02c"


def _frame_segments(centres: np.ndarray, normals: np.ndarray, sizes: np.ndarray, bar: float = 0.05) -> list:
    """Top-view outline of each frame: the segment across its posts."""
    segs = []
    for c, n, (w, _) in zip(centres, normals, sizes, strict=True):
        a = np.array([n[0], n[1]]) / max(np.hypot(n[0], n[1]), 1e-12)
        across = np.array([-a[1], a[0]])
        segs.append(np.array([c[:2] - (w / 2 + bar) * across, c[:2] + (w / 2 + bar) * across]))
    return segs


def _paths(result: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t, p = result.states["t"], result.states["p_W"]
    est = result.topics.get(str(Topics.ESTIMATE), {})
    sp = result.topics.get(str(Topics.TRAJECTORY_SETPOINT), {})
    te = np.asarray(est.get("t", np.zeros(0)), float)
    pe = np.asarray(est.get("p_W", np.zeros((0, 3))), float).reshape(-1, 3)
    ts = np.asarray(sp.get("t", np.zeros(0)), float)
    ps = np.asarray(sp.get("p_W", np.zeros((0, 3))), float).reshape(-1, 3)
    return t, p, te, pe, ts, ps


def plot_tunnel_trajectory(path: str | Path, result: Any, mission: Any, course: Any, title: str = "") -> Path:
    """Fig. 8 style: top view (x-y) of the true path (red), the odometry (blue) and the setpoints (green) with the
    true frames (black) and the detected ones (orange, dashed); right: height over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, p, te, pe, ts, ps = _paths(result)
    fig, (ax, az) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [2.2, 1]})
    ax.plot(ps[:, 0], ps[:, 1], color=_GREEN, lw=1.2, label="trajectory setpoint")
    ax.plot(pe[:, 0], pe[:, 1], color=_BLUE, lw=1.0, label="odometry (LIO)")
    ax.plot(p[:, 0], p[:, 1], color=_RED, lw=1.0, ls="--", label="drone pose (truth)")
    if course is not None:
        c, n, s, bar = true_frames(course)
        for k, seg in enumerate(_frame_segments(c, n, s, bar)):
            ax.plot(
                seg[:, 0], seg[:, 1], color="k", lw=3, solid_capstyle="butt", label="frames (truth)" if k == 0 else None
            )
    d = mission.used
    if d is not None:
        for k, seg in enumerate(_frame_segments(d.centres, d.normals, d.sizes)):
            ax.plot(
                seg[:, 0], seg[:, 1], color="tab:orange", lw=1.5, ls=":", label="frames (detected)" if k == 0 else None
            )
        ax.plot(d.centres[:, 0], d.centres[:, 1], "x", color="tab:orange")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or "tunnel mission, top view")
    az.plot(ts, ps[:, 2], color=_GREEN, lw=1.2, label="setpoint")
    az.plot(te, pe[:, 2], color=_BLUE, lw=1.0, label="odometry")
    az.plot(t, p[:, 2], color=_RED, lw=1.0, ls="--", label="truth")
    for tt, state, _ in mission.transitions[1:]:
        az.axvline(tt, color="0.7", lw=0.8)
        az.text(tt, az.get_ylim()[1] if False else 0.02, state, rotation=90, fontsize=7, va="bottom", color="0.4")
    az.set_xlabel("t [s]")
    az.set_ylabel("z [m]")
    az.grid(True, alpha=0.3)
    az.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_tunnel_replay(
    path: str | Path, result: Any, params: Any, world: Any, mission: Any, clouds: list[np.ndarray], fps: int = 20
) -> Path:
    """A self-contained MeshCat replay: the world's meshes, the vehicle flying, the true (red), odometry (blue)
    and setpoint (green) paths, the detected centres, and point-cloud snapshots (world frame)."""
    from cufund.viz.meshcat_scene import (
        VEHICLE,
        draw_path,
        draw_vehicle,
        import_meshcat,
        pose_matrix,
    )
    from cufund.viz.replay import _RecordingWindow, viewer_page

    meshcat = import_meshcat()
    g = meshcat.geometry
    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    if world is not None:
        for obj in world.objects:
            if obj.label in ("ceiling",):
                continue
            color = int(255 * obj.color[0]) << 16 | int(255 * obj.color[1]) << 8 | int(255 * obj.color[2])
            opacity = 0.25 if obj.label == "wall" else 1.0
            vis[f"world/{obj.label}_{obj.id}"].set_object(
                g.TriangularMeshGeometry(np.asarray(obj.vertices, float), np.asarray(obj.triangles)),
                g.MeshLambertMaterial(color=color, opacity=opacity, transparent=opacity < 1),
            )
    draw_vehicle(vis, params)
    t, p, _, pe, _, ps = _paths(result)
    q = result.states["q_WB"]
    draw_path(vis, "paths/truth", p[:: max(1, len(t) // 3000)], 0xD62728)
    if len(pe):
        draw_path(vis, "paths/odometry", pe[:: max(1, len(pe) // 3000)], 0x1F77B4)
    if len(ps):
        draw_path(vis, "paths/setpoints", ps[:: max(1, len(ps) // 3000)], 0x2CA02C)
    d = mission.used
    if d is not None:
        for k, c in enumerate(d.centres):
            vis[f"detections/centre_{k}"].set_object(g.Sphere(0.04), g.MeshLambertMaterial(color=0xFF7F0E))
            vis[f"detections/centre_{k}"].set_transform(pose_matrix(c, np.array([1.0, 0, 0, 0])))
    for k, pts in enumerate(clouds):
        pts = np.asarray(pts, dtype=np.float32).reshape(-1, 3)
        if pts.shape[0]:
            col = np.tile(np.array([[0.2, 0.6, 0.9]], np.float32), (pts.shape[0], 1))
            vis[f"clouds/snapshot_{k}"].set_object(g.PointsGeometry(pts.T, col.T), g.PointsMaterial(size=0.02))
    frames = np.arange(t[0], t[-1], 1.0 / fps)
    idx = np.clip(np.searchsorted(t, frames), 0, len(t) - 1)
    anim = meshcat.animation.Animation(default_framerate=fps)
    for k, i in enumerate(idx):
        with anim.at_frame(vis, k) as frame:
            frame[VEHICLE].set_transform(pose_matrix(p[i], q[i]))
    vis.set_animation(anim, play=True, repetitions=1)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [-4.0, 5.0, 4.0])
    path = Path(path)
    path.write_text(viewer_page(window.commands), encoding="utf-8")
    return path


def _cloud(detector: Any) -> np.ndarray:
    """The detector's accumulated map (voxel means, world frame) [m]."""
    try:
        return np.asarray(detector.map_points_W(), dtype=float)
    except (AttributeError, ZeroDivisionError, ValueError):
        return np.zeros((0, 3))


def write_tunnel_outputs(
    run: Any, out: str | Path, mission: Any, course: Any, detector: list[Any], plots: bool = True, replay: bool = True
) -> None:
    """Writes trajectory.png, detection.png and replay.html of a tunnel run into ``out``."""
    out = Path(out)
    m = run.metrics
    if plots:
        rmse, mx = m.get("tracking_rmse_m"), m.get("tracking_max_m")
        orm = m.get("odometry_rmse_m")
        title = (
            f"tunnel ({run.config.controller.kind if run.config.controller else '-'}): {m.get('status')}"
            + (f", tracking RMSE {100 * rmse:.2f} cm / max {100 * mx:.2f} cm" if rmse is not None else "")
            + (f", odometry RMSE {100 * orm:.2f} cm" if orm is not None else "")
        )
        plot_tunnel_trajectory(out / "trajectory.png", run.result, mission, course, title)
        _detection_plot(out / "detection.png", detector, course, mission)
    if replay:
        world = getattr(run, "world", None)
        if world is None and course is not None:
            world = course.world
        write_tunnel_replay(
            out / "replay.html", run.result, run.config.vehicle_params(), world, mission, [_cloud(detector)]
        )


def _detection_plot(path: Path, detector: Any, course: Any, mission: Any) -> None:
    """The detector's Fig.-9-style plot of its map and tracked frames, with the true centres."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if _cloud(detector).shape[0] == 0:
        return
    truth = None if course is None else np.array([f.centre_W for f in course.frames])
    fig = detector.plot(path, truth)
    plt.close(fig)

"""A self-contained MeshCat replay of a run: one HTML file with the viewer and the animation, no server.

It shows the world (any world kind, :mod:`.world_scene`), the vehicle (enlarged when the flight is large, and
said so in the legend), the planned path, the flown (true) path and the estimate, what the run's parts add
(:class:`~cufund.viz.flight.Overlay`), framed on the flight (:func:`~cufund.viz.meshcat_scene.frame_view`), with a
legend and MeshCat's animation controls open."""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

import numpy as np

from cufund.vehicle.params import QuadrotorParams

from .flight import Flight
from .meshcat_scene import (
    ESTIMATE_COLOR,
    ESTIMATE_VEHICLE,
    ESTIMATED,
    FLOWN,
    PLANNED,
    PLANNED_COLOR,
    SETPOINT,
    TRUTH_COLOR,
    VEHICLE,
    View,
    apply_view,
    draw_estimate_marker,
    draw_path,
    draw_vehicle,
    frame_view,
    import_meshcat,
    pose_matrix,
    vehicle_scale,
)
from .world_scene import draw_world

__all__ = ["LegendEntry", "replay_html", "viewer_page", "write_replay_html"]

LegendEntry = tuple[str, int, str]
"""(text, 0xRRGGBB, "line" | "box" | "dot")."""
MAX_FRAMES = 1800
"""Animation frames at most (a long run is animated at a lower frame rate)."""


class _RecordingWindow:
    """Stands in for meshcat's server connection and keeps the encoded commands instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command: Any) -> None:
        import umsgpack

        self.commands.append(umsgpack.packb(command.lower()))


def _thin(points: np.ndarray, n: int = 3000) -> np.ndarray:
    return points[:: max(1, len(points) // n)]


def replay_html(
    flight: Flight, params: QuadrotorParams, world: Any = None, fps: int = 30, size: tuple[int, int] = (800, 600)
) -> str:
    """The HTML text of a replay of ``flight`` in ``world`` (None: MeshCat's ground grid only)."""
    meshcat = import_meshcat()
    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    view = frame_view(flight.framing_points(), aspect=size[0] / size[1])
    apply_view(vis, view)
    world_legend = [] if world is None else [(label, color, "box") for label, color in draw_world(vis, world)]
    scale = vehicle_scale(params, view)
    draw_vehicle(vis, params, scale)
    legend: list[LegendEntry] = [(f"vehicle (drawn {scale:.0f}x size)" if scale > 1.5 else "vehicle", 0x404040, "box")]
    t, p, q = flight.t, flight.p_W, flight.q_WB
    paths = [(FLOWN, p, TRUTH_COLOR, "flown (truth)")]
    if len(flight.p_est_W):
        paths.append((ESTIMATED, flight.p_est_W, ESTIMATE_COLOR, "estimate"))
        draw_estimate_marker(vis, params, scale)
    if len(flight.planned_W) >= 2:
        paths.append(
            (PLANNED, flight.planned_W, PLANNED_COLOR, "planned" if flight.planned_is_reference else "setpoints")
        )
    for name, pts, color, label in paths:
        if len(pts) >= 2:
            draw_path(vis, name, _thin(pts), color)
            legend.append((label, color, "line"))
    legend += world_legend
    g = meshcat.geometry
    for overlay in flight.overlays:
        pts = np.asarray(overlay.points_W, dtype=np.float32).reshape(-1, 3)
        if not len(pts):
            continue
        node = vis["overlays"][overlay.name]
        if overlay.kind == "cloud":
            colors = np.tile(
                np.array([[(overlay.color >> s & 255) / 255.0 for s in (16, 8, 0)]], np.float32), (len(pts), 1)
            )
            node.set_object(g.PointsGeometry(pts.T, colors.T), g.PointsMaterial(size=0.01 * max(1.0, view.radius / 5)))
        else:
            for k, c in enumerate(pts):
                node[str(k)].set_object(g.Sphere(0.04 * scale), g.MeshLambertMaterial(color=overlay.color))
                node[str(k)].set_transform(pose_matrix(c, np.array([1.0, 0, 0, 0])))
        legend.append((overlay.label or overlay.name, overlay.color, "dot"))

    if len(t) >= 2:
        duration = float(t[-1] - t[0])
        fps = int(max(5, min(fps, MAX_FRAMES / max(duration, 1e-9))))
        frames = np.arange(t[0], t[-1], 1.0 / fps)
        idx = np.clip(np.searchsorted(t, frames), 0, len(t) - 1)
        est_idx = np.clip(np.searchsorted(flight.t_est, frames, side="right") - 1, 0, None)
        sp_idx = np.clip(np.searchsorted(flight.t_sp, frames, side="right") - 1, 0, None)
        anim = meshcat.animation.Animation(default_framerate=fps)
        one = np.array([1.0, 0, 0, 0])
        for k, i in enumerate(idx):
            with anim.at_frame(vis, k) as frame:
                frame[VEHICLE].set_transform(pose_matrix(p[i], q[i]))
                if len(flight.t_est):
                    j = est_idx[k]
                    frame[ESTIMATE_VEHICLE].set_transform(pose_matrix(flight.p_est_W[j], flight.q_est_WB[j]))
                if len(flight.t_sp):
                    frame[SETPOINT].set_transform(pose_matrix(flight.p_sp_W[sp_idx[k]], one))
        vis.set_animation(anim, play=True, repetitions=1)
    return viewer_page(window.commands, legend, view, title=flight.title)


def viewer_page(
    commands: list[bytes], legend: list[LegendEntry] | tuple = (), view: View | None = None, title: str = ""
) -> str:
    """A standalone HTML page: MeshCat's viewer script inlined, then the encoded scene ``commands``, a legend and
    MeshCat's controls opened on the animation slider. The camera (``view``) is in the page as JSON
    (``<script id="cufund-view">``: ``eye_W``, ``target_W``, ``up_W``, ``fov_deg``) for tools and tests."""
    viewer_js = (Path(import_meshcat().__file__).parent / "viewer" / "dist" / "main.min.js").read_text(encoding="utf-8")
    calls = "\n".join(
        f'fetch("data:application/octet-binary;base64,{base64.b64encode(c).decode()}").then(r => r.arrayBuffer())'
        ".then(b => viewer.handle_command_bytearray(new Uint8Array(b)));"
        for c in commands
    )
    items = "\n".join(
        f'<div class="item"><span class="{kind}" style="background:#{color:06x}"></span>{html.escape(text)}</div>'
        for text, color, kind in legend
    )
    heading = f"<div class='title'>{html.escape(title)}</div>" if title else ""
    legend_div = f'<div id="cufund-legend">{heading}{items}</div>' if (items or heading) else ""
    view_json = json.dumps(view.to_dict() if view is not None else None)
    return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>cufund replay</title>
<style>body {{ margin: 0; }} #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#cufund-legend {{ position: absolute; left: 8px; bottom: 8px; background: rgba(255,255,255,0.85); padding: 6px 9px;
  font: 12px sans-serif; color: #222; border-radius: 4px; pointer-events: none; }}
#cufund-legend .title {{ font-weight: bold; margin-bottom: 3px; }}
#cufund-legend .item {{ line-height: 17px; white-space: nowrap; }}
#cufund-legend span {{ display: inline-block; margin-right: 6px; vertical-align: middle; }}
#cufund-legend .line {{ width: 18px; height: 3px; }}
#cufund-legend .box {{ width: 12px; height: 12px; margin: 0 9px 0 3px; }}
#cufund-legend .dot {{ width: 9px; height: 9px; border-radius: 50%; margin: 0 10px 0 5px; }}</style></head>
<body>
<div id="meshcat-pane"></div>
{legend_div}
<script id="cufund-view" type="application/json">{view_json}</script>
<script>{viewer_js}</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
{calls}
viewer.gui.open();  // MeshCat's controls, folded to the animation's play / pause / time slider
Object.values(viewer.gui.__folders).forEach(f => f.close());
viewer.animator.folder.open();
</script>
</body>
</html>
"""


def write_replay_html(
    path: str | Path, flight: Flight, params: QuadrotorParams, world: Any = None, fps: int = 30
) -> Path:
    """Writes :func:`replay_html` to ``path``; returns the path."""
    path = Path(path)
    path.write_text(replay_html(flight, params, world, fps), encoding="utf-8")
    return path

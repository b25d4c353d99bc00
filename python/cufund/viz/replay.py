"""A self-contained MeshCat replay of a run: one HTML file with the viewer and the animation, no server."""

from __future__ import annotations

import base64
from pathlib import Path
from typing import Any

import numpy as np

from cufund.planning.trajectory import Trajectory
from cufund.simulator import SimulationResult
from cufund.vehicle.params import QuadrotorParams

from .meshcat_scene import FLOWN, PLANNED, SETPOINT, VEHICLE, draw_path, draw_vehicle, import_meshcat, pose_matrix

__all__ = ["replay_html", "viewer_page", "write_replay_html"]


class _RecordingWindow:
    """Stands in for meshcat's server connection and keeps the encoded commands instead of sending them."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command: Any) -> None:
        import umsgpack

        self.commands.append(umsgpack.packb(command.lower()))


def replay_html(
    result: SimulationResult, params: QuadrotorParams, planned: Trajectory | None = None, fps: int = 30
) -> str:
    """The HTML text of a replay of ``result`` (vehicle, flown path, and ``planned`` with its moving setpoint)."""
    meshcat = import_meshcat()
    Animation = meshcat.animation.Animation

    window = _RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    draw_vehicle(vis, params)
    t, p, q = result.states["t"], result.states["p_W"], result.states["q_WB"]
    draw_path(vis, FLOWN, p[:: max(1, len(t) // 2000)], 0xD62728)
    frames = np.arange(t[0], t[-1], 1.0 / fps)
    idx = np.clip(np.searchsorted(t, frames), 0, len(t) - 1)
    if planned is not None:
        tt = np.linspace(t[0], t[-1], 2000)
        draw_path(vis, PLANNED, planned.sample(tt).p_W, 0x1F77B4)
        sp = planned.sample(frames).p_W
    anim = Animation(default_framerate=fps)
    for k, i in enumerate(idx):
        with anim.at_frame(vis, k) as frame:
            frame[VEHICLE].set_transform(pose_matrix(p[i], q[i]))
            if planned is not None:
                frame[SETPOINT].set_transform(pose_matrix(sp[k], np.array([1.0, 0, 0, 0])))
    vis.set_animation(anim, play=True, repetitions=1)
    # Camera position in MeshCat's y-up camera frame, (world x, world z, -world y): 2.6 m south-east of the
    # origin and 2.6 m up, far enough that the square, the ground grid and the climb are all in view.
    vis["/Cameras/default/rotated/<object>"].set_property("position", [2.0, 2.6, 2.6])
    return viewer_page(window.commands)


def viewer_page(commands: list[bytes]) -> str:
    """A standalone HTML page: MeshCat's viewer script inlined, then the encoded scene ``commands``."""
    viewer_js = (Path(import_meshcat().__file__).parent / "viewer" / "dist" / "main.min.js").read_text(encoding="utf-8")
    calls = "\n".join(
        f'fetch("data:application/octet-binary;base64,{base64.b64encode(c).decode()}").then(r => r.arrayBuffer())'
        ".then(b => viewer.handle_command_bytearray(new Uint8Array(b)));"
        for c in commands
    )
    return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>cufund replay</title>
<style>body {{ margin: 0; }} #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}</style></head>
<body>
<div id="meshcat-pane"></div>
<script>{viewer_js}</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
{calls}
</script>
</body>
</html>
"""


def write_replay_html(
    path: str | Path,
    result: SimulationResult,
    params: QuadrotorParams,
    planned: Trajectory | None = None,
    fps: int = 30,
) -> Path:
    """Writes :func:`replay_html` to ``path``; returns the path."""
    path = Path(path)
    path.write_text(replay_html(result, params, planned, fps), encoding="utf-8")
    return path

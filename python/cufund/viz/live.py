"""Streaming a run to MeshCat in the browser while it simulates (``cufund run ... --viz``)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from cufund.core.components import BusView, Component
from cufund.core.messages import Topics
from cufund.planning.trajectory import Trajectory
from cufund.vehicle.params import QuadrotorParams

from .meshcat_scene import (
    FLOWN,
    PLANNED,
    PLANNED_COLOR,
    SETPOINT,
    TRUTH_COLOR,
    VEHICLE,
    draw_path,
    draw_vehicle,
    pose_matrix,
)

__all__ = ["LiveViewer"]


class LiveViewer(Component):
    """A component that draws the vehicle, the planned path, the flown path and the current setpoint in MeshCat
    at ``rate_hz``, pacing the simulation to ``speed`` times real time (None: as fast as it runs).

    Starts a MeshCat server bound to 127.0.0.1 unless a ``visualizer`` is given; its URL is ``self.url``.
    """

    name = "live_viewer"
    reads_truth = True
    inputs = (Topics.TRUTH_ODOMETRY,)
    optional_inputs = (Topics.TRAJECTORY_SETPOINT,)

    def __init__(
        self,
        params: QuadrotorParams,
        planned: Trajectory | None = None,
        rate_hz: float = 25.0,
        speed: float | None = 1.0,
        visualizer: Any = None,
    ) -> None:
        self.rate_hz = rate_hz
        self.speed = speed
        self.server = None
        if visualizer is None:
            from .meshcat_server import start_server

            visualizer, self.server = start_server()
        self.vis = visualizer
        self.url: str | None = getattr(self.vis.window, "web_url", None)
        self.vis.delete()
        draw_vehicle(self.vis, params)
        if planned is not None:
            tt = np.linspace(planned.t_start, planned.t_start + planned.duration, 2000)
            draw_path(self.vis, PLANNED, planned.sample(tt).p_W, PLANNED_COLOR)
        self._flown: list[np.ndarray] = []
        self._wall0: float | None = None
        self._t0 = 0.0

    def close(self) -> None:
        """Closes the connection and stops the server this viewer started."""
        socket = getattr(self.vis.window, "zmq_socket", None)
        if socket is not None:
            socket.close()
        if self.server is not None:
            self.server.terminate()
            self.server.wait(timeout=10)
            self.server = None

    def reset(self) -> None:
        self._flown = []
        self._wall0 = None

    def step(self, t: float, bus: BusView) -> None:
        truth = bus.latest(Topics.TRUTH_ODOMETRY)
        if truth is None:
            return
        if self._wall0 is None:
            self._wall0, self._t0 = time.perf_counter(), t
        self.vis[VEHICLE].set_transform(pose_matrix(truth.p_W, truth.q_WB))
        sp = bus.latest(Topics.TRAJECTORY_SETPOINT)
        if sp is not None:
            self.vis[SETPOINT].set_transform(pose_matrix(sp.p_W, np.array([1.0, 0.0, 0.0, 0.0])))
        self._flown.append(truth.p_W.copy())
        if len(self._flown) >= 2 and len(self._flown) % 5 == 0:
            draw_path(self.vis, FLOWN, np.array(self._flown), TRUTH_COLOR)
        if self.speed:
            ahead = (t - self._t0) / self.speed - (time.perf_counter() - self._wall0)
            if ahead > 0:
                time.sleep(ahead)

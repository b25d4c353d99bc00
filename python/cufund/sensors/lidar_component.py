"""A LiDAR as a simulator component: publishes one motion-distorted frame per scan period."""

from __future__ import annotations

import numpy as np

from ..components import Bus, Component
from ..messages import Odometry, Topics
from ..worlds.world import World
from .lidar import Lidar


class LidarComponent(Component):
    """Runs ``lidar`` in a :class:`cufund.Simulator` against ``world``.

    The component runs at ``rate_hz`` (the rate at which it samples the ground-truth pose; it must divide
    the physics rate and be a multiple of the LiDAR's frame rate). At the end of each frame it casts the
    whole frame, every ray from the pose at its own firing time (interpolated between the recorded poses),
    and publishes the :class:`cufund.sensors.PointCloud` on ``topic`` — one frame late, like a real driver.
    """

    name = "lidar"

    def __init__(self, lidar: Lidar, world: World, topic: str = Topics.POINT_CLOUD, rate_hz: float = 100.0) -> None:
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World, got {type(world).__name__}")
        per_frame = rate_hz * lidar.period
        if not (np.isfinite(per_frame) and per_frame >= 1 and abs(per_frame - round(per_frame)) < 1e-9):
            raise ValueError(f"rate_hz must be a multiple of the LiDAR frame rate {1 / lidar.period:g} Hz, got {rate_hz}")
        self.lidar, self.world, self.topic, self.rate_hz = lidar, world, topic, float(rate_hz)
        self.reset()

    def reset(self) -> None:
        self.lidar.reset()
        self._t: list[float] = []
        self._p: list[np.ndarray] = []
        self._q: list[np.ndarray] = []
        self._frame_start: float | None = None

    def _pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        ts = self._t
        i = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2))
        s = float(np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0))
        q0, q1 = self._q[i], self._q[i + 1]
        if np.dot(q0, q1) < 0:
            q1 = -q1
        q = (1 - s) * q0 + s * q1  # the lidar model interpolates finely between its own pose samples
        return (1 - s) * self._p[i] + s * self._p[i + 1], q / np.linalg.norm(q)

    def step(self, t: float, bus: Bus) -> None:
        truth: Odometry = bus.get(Topics.GROUND_TRUTH)
        self._t.append(t)
        self._p.append(np.asarray(truth.p_W, dtype=float).copy())
        self._q.append(np.asarray(truth.q_WB, dtype=float).copy())
        if self._frame_start is None:
            self._frame_start = t
        period = self.lidar.period
        if t - self._frame_start >= period - 1e-9:
            bus.publish(self.topic, self.lidar.scan(self.world, self._pose, self._frame_start))
            self._frame_start += period
            keep = max(0, int(np.searchsorted(self._t, self._frame_start, side="right")) - 1)
            del self._t[:keep], self._p[:keep], self._q[:keep]

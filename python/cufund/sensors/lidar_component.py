"""A LiDAR as a simulator component: publishes one motion-distorted frame per scan period."""

from __future__ import annotations

import numpy as np

from cufund.core.components import BusView, Component
from cufund.core.messages import LidarTruth, Odometry, PointCloud, Topics
from cufund.core.topics import Topic
from cufund.worlds.world import World

from .lidar import Lidar


class LidarComponent(Component):
    """Runs ``lidar`` in a :class:`cufund.Simulator` against ``world``.

    The component runs at ``rate_hz``, the rate at which it samples the true pose (a multiple of the LiDAR's
    frame rate). At the end of each frame it casts the whole frame, every ray from the pose at its own firing
    time (interpolated between the sampled poses), and publishes the :class:`~cufund.core.messages.PointCloud`
    (stamped with the frame's start) on ``topic`` — at the frame's end, like a real driver, plus ``latency_s`` —
    and the frame's ground truth (:class:`~cufund.core.messages.LidarTruth`) on ``truth_topic``.
    """

    name = "lidar"
    reads_truth = True

    def __init__(
        self,
        lidar: Lidar,
        world: World,
        topic: str = Topics.POINT_CLOUD,
        rate_hz: float = 100.0,
        truth_topic: str | None = None,
        latency_s: float = 0.0,
    ) -> None:
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World, got {type(world).__name__}")
        per_frame = rate_hz * lidar.period
        if not (np.isfinite(per_frame) and per_frame >= 1 and abs(per_frame - round(per_frame)) < 1e-9):
            raise ValueError(
                f"rate_hz must be a multiple of the LiDAR frame rate {1 / lidar.period:g} Hz, got {rate_hz}"
            )
        self.lidar, self.world, self.rate_hz, self.latency_s = lidar, world, float(rate_hz), float(latency_s)
        self.topic = topic if isinstance(topic, Topic) else Topic(topic, PointCloud)
        if truth_topic is None:
            truth_topic = Topics.TRUTH_POINT_CLOUD if self.topic == Topics.POINT_CLOUD else "/truth" + self.topic
        self.truth_topic = Topic(str(truth_topic), LidarTruth)
        self.inputs = (Topics.TRUTH_ODOMETRY,)
        self.outputs = (self.topic, self.truth_topic)
        self.reset()

    def reset(self) -> None:
        self.lidar.reset()
        self._t: list[float] = []
        self._p: list[np.ndarray] = []
        self._q: list[np.ndarray] = []
        self._frame_start: float | None = None
        self._pose_fn = _PoseFn(self)

    def _pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        ts = self._t
        i = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2))
        s = float(np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0))
        q0, q1 = self._q[i], self._q[i + 1]
        if np.dot(q0, q1) < 0:
            q1 = -q1
        q = (1 - s) * q0 + s * q1  # the lidar model interpolates finely between its own pose samples
        return (1 - s) * self._p[i] + s * self._p[i + 1], q / np.linalg.norm(q)

    def _poses(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_pose` at every time of ``times`` (K,), unit and sign-aligned as ``sample_poses`` makes them:
        positions (K, 3) and quaternions (K, 4), the same numbers (the norms taken row by row, as there)."""
        ts = np.asarray(self._t)
        i = np.clip(np.searchsorted(ts, times, side="right") - 1, 0, len(ts) - 2)
        s = np.clip((times - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0)[:, None]
        P, Q = np.asarray(self._p), np.asarray(self._q)
        q0, q1 = Q[i], Q[i + 1]
        q1 = np.where((np.einsum("ij,ij->i", q0, q1) < 0)[:, None], -q1, q1)
        q = (1 - s) * q0 + s * q1
        # np.linalg.norm of one row is sqrt(row.dot(row)): the same call, without its per-call overhead
        q = q / np.sqrt([r.dot(r) for r in q])[:, None]
        q = q / np.sqrt([r.dot(r) for r in q])[:, None]  # sample_poses normalises what pose_fn returns
        for k in range(1, len(q)):
            if np.dot(q[k], q[k - 1]) < 0:
                q[k] = -q[k]
        return (1 - s) * P[i] + s * P[i + 1], q

    def step(self, t: float, bus: BusView) -> None:
        truth: Odometry = bus.latest(Topics.TRUTH_ODOMETRY)
        self._t.append(t)
        self._p.append(truth.p_W)
        self._q.append(truth.q_WB)
        if self._frame_start is None:
            self._frame_start = t
        period = self.lidar.period
        if t - self._frame_start >= period - 1e-9:
            cloud, hits = self.lidar.scan_with_truth(self.world, self._pose_fn, self._frame_start)
            bus.publish(self.topic, cloud)
            bus.publish(self.truth_topic, hits)
            self._frame_start += period
            keep = max(0, int(np.searchsorted(self._t, self._frame_start, side="right")) - 1)
            del self._t[:keep], self._p[:keep], self._q[:keep]


class _PoseFn:
    """The component's true pose as a ``pose_fn`` for :meth:`Lidar.scan_with_truth`, with ``many``."""

    def __init__(self, component: LidarComponent) -> None:
        self.component = component

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.component._pose(t)

    def many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.component._poses(np.asarray(times, dtype=float))

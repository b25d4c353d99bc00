"""The ESDF map as a simulator component: integrates the LiDAR point clouds published on the bus."""

from __future__ import annotations

import numpy as np

from ..components import Bus, Mapper
from ..messages import Odometry, PointCloud, Topics
from ..sensors.pose import Transform, quat_to_matrix
from .esdf_map import EsdfMap, EsdfMapParams


class EsdfMapper(Mapper):
    """Keeps an :class:`EsdfMap` up to date from the :class:`~cufund.messages.PointCloud` frames on
    ``cloud_topic``, placed in the world with the vehicle pose read from ``state_topic``.

    Every point is measured in the LiDAR frame at its own firing time (``points_L``, motion-distorted); the
    mapper moves it to the world frame with the body pose at that time, interpolated between the poses it
    has seen, and the LiDAR extrinsic ``T_BL`` (so with an estimator's topic the map carries the estimate's
    errors, as a real one would). Each frame's beams are cast from the LiDAR position at the middle of the
    frame. Run it at least as often as the LiDAR component samples poses.
    """

    name = "esdf_mapper"

    def __init__(self, params: EsdfMapParams, T_BL: Transform | None = None, rate_hz: float = 100.0,
                 state_topic: str = Topics.GROUND_TRUTH, cloud_topic: str = Topics.POINT_CLOUD) -> None:
        if not isinstance(params, EsdfMapParams):
            raise ValueError(f"params must be an EsdfMapParams, got {type(params).__name__}")
        self.params, self.T_BL, self.rate_hz = params, T_BL or Transform(), float(rate_hz)
        self.state_topic, self.cloud_topic = state_topic, cloud_topic
        self.reset()

    def reset(self) -> None:
        self.map = EsdfMap(self.params)
        self.frames = 0
        self._last: PointCloud | None = None
        self._t: list[float] = []
        self._p: list[np.ndarray] = []
        self._q: list[np.ndarray] = []

    def _poses(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body positions (N, 3) and rotations (N, 3, 3) at times t, interpolated (clamped at the ends)."""
        ts = np.asarray(self._t)
        p, q = np.asarray(self._p), np.asarray(self._q)
        if len(ts) == 1:
            return np.repeat(p, len(t), axis=0), np.repeat(quat_to_matrix(q), len(t), axis=0)
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
        s = np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0)[:, None]
        q0, q1 = q[i], q[i + 1]
        q1 = np.where(np.sum(q0 * q1, axis=1, keepdims=True) < 0, -q1, q1)
        qs = (1 - s) * q0 + s * q1
        return (1 - s) * p[i] + s * p[i + 1], quat_to_matrix(qs / np.linalg.norm(qs, axis=1, keepdims=True))

    def integrate(self, t: float, bus: Bus) -> None:
        state: Odometry | None = bus.get(self.state_topic)
        if state is not None and (not self._t or t > self._t[-1]):
            self._t.append(t)
            self._p.append(np.asarray(state.p_W, dtype=float).copy())
            self._q.append(np.asarray(state.q_WB, dtype=float).copy())
        cloud: PointCloud | None = bus.get(self.cloud_topic)
        if cloud is None or cloud is self._last or not self._t:
            return
        self._last = cloud
        R_BL, t_BL = self.T_BL.R, np.asarray(self.T_BL.t)
        p_WB, R_WB = self._poses(np.asarray(cloud.t, dtype=float))
        p_WL = p_WB + R_WB @ t_BL
        points_W = p_WL + np.einsum("nij,nj->ni", R_WB @ R_BL, np.asarray(cloud.points_L, dtype=float))
        mid_p, mid_R = self._poses(np.array([cloud.t0 + 0.5 * (cloud.t.max() - cloud.t0 if len(cloud.t) else 0.0)]))
        self.map.insert_scan(points_W, mid_p[0] + mid_R[0] @ t_BL)
        self.frames += 1
        # Keep only the poses a later frame can need.
        keep = max(0, int(np.searchsorted(self._t, cloud.t0, side="right")) - 1)
        del self._t[:keep], self._p[:keep], self._q[:keep]

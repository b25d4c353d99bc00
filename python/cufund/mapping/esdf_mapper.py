"""The ESDF map as a simulator component: integrates every LiDAR frame, placed with the vehicle's pose."""

from __future__ import annotations

import numpy as np

from ..components import BusView, Mapper, Subscription
from ..messages import MapUpdate, Odometry, PointCloud, Topics
from ..sensors.pose import Transform, interpolate_poses
from .esdf_map import EsdfMap, EsdfMapParams


class EsdfMapper(Mapper):
    """Keeps an :class:`EsdfMap` up to date from every :class:`~cufund.messages.PointCloud` frame on
    ``cloud_topic``, placed in the world with the vehicle poses on its state topic, and announces each update
    as a :class:`~cufund.messages.MapUpdate` on ``Topics.ESDF_MAP``.

    Its pose is the estimator's output when one is attached (ground truth otherwise, or ``state_topic`` if
    given), so the map carries the estimate's errors as a real one would. Every point is measured in the LiDAR
    frame at its own firing time; the mapper moves it to the world frame with the body pose at that time
    (interpolated between the poses it received) and the LiDAR extrinsic ``T_BL``. Each frame's beams are cast
    from the LiDAR position at the middle of the frame. A frame waits until poses up to its last point have
    arrived; none is skipped, however slowly the mapper runs.
    """

    name = "esdf_mapper"

    def __init__(self, params: EsdfMapParams, T_BL: Transform | None = None, rate_hz: float = 100.0,
                 state_topic: str | None = None, cloud_topic: str = Topics.POINT_CLOUD) -> None:
        if not isinstance(params, EsdfMapParams):
            raise ValueError(f"params must be an EsdfMapParams, got {type(params).__name__}")
        self.params, self.T_BL, self.rate_hz = params, T_BL or Transform(), float(rate_hz)
        self.state_topic, self.cloud_topic = state_topic, cloud_topic
        self.active_state_topic: str = Topics.TRUTH_ODOMETRY
        self.outputs = (Topics.ESDF_MAP,)
        self.reset()

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.active_state_topic, self.cloud_topic)

    def reset(self) -> None:
        self.map = EsdfMap(self.params)
        self.frames = 0
        self._t: list[float] = []
        self._p: list[np.ndarray] = []
        self._q: list[np.ndarray] = []
        self._waiting: list[PointCloud] = []

    def setup(self, bus: BusView) -> None:
        self._poses_sub: Subscription = bus.subscribe(self.active_state_topic)
        self._clouds_sub: Subscription = bus.subscribe(self.cloud_topic)

    def _poses(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body positions (N, 3) and rotations (N, 3, 3) at times t, interpolated (clamped at the ends)."""
        return interpolate_poses(self._t, self._p, self._q, t)

    def integrate(self, t: float, bus: BusView) -> None:
        for state in self._poses_sub.take():
            state: Odometry
            if not self._t or state.t > self._t[-1]:
                self._t.append(state.t)
                self._p.append(state.p_W)
                self._q.append(state.q_WB)
        self._waiting.extend(self._clouds_sub.take())
        updated = False
        while self._waiting and self._t and self._t[-1] >= self._waiting[0].t + float(np.max(self._waiting[0].dt, initial=0.0)):
            self._insert(self._waiting.pop(0))
            updated = True
        if updated:
            bus.publish(Topics.ESDF_MAP, MapUpdate(self._last_stamp, self.map, self.frames))

    def _insert(self, cloud: PointCloud) -> None:
        R_BL, t_BL = self.T_BL.R, np.asarray(self.T_BL.t)
        t_points = cloud.t + np.asarray(cloud.dt, dtype=float)
        p_WB, R_WB = self._poses(t_points)
        p_WL = p_WB + R_WB @ t_BL
        points_W = p_WL + np.einsum("nij,nj->ni", R_WB @ R_BL, np.asarray(cloud.points_L, dtype=float))
        mid_p, mid_R = self._poses(np.array([cloud.t + 0.5 * float(np.max(cloud.dt, initial=0.0))]))
        self.map.insert_scan(points_W, mid_p[0] + mid_R[0] @ t_BL)
        self.frames += 1
        self._last_stamp = cloud.t
        # Keep only the poses a later frame can need.
        keep = max(0, int(np.searchsorted(self._t, cloud.t, side="right")) - 1)
        del self._t[:keep], self._p[:keep], self._q[:keep]

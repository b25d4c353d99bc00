"""The ESDF map as a simulator component: integrates every LiDAR frame, placed with the vehicle's pose."""

from __future__ import annotations

import numpy as np

from cufund.core.components import BusView, Mapper, Subscription
from cufund.core.messages import MapUpdate, Odometry, PointCloud, Topics
from cufund.geometry import Transform

from .esdf_map import EsdfMap, EsdfMapParams


class EsdfMapper(Mapper):
    """Keeps an :class:`EsdfMap` up to date from every :class:`~cufund.core.messages.PointCloud` frame on
    ``cloud_topic``, placed in the world with the vehicle poses on its state topic, and announces each update
    as a :class:`~cufund.core.messages.MapUpdate` on ``Topics.ESDF_MAP``.

    Its pose is the estimator's output when one is attached (ground truth otherwise, or ``state_topic`` if
    given), so the map carries the estimate's errors as a real one would. Every point is measured in the LiDAR
    frame at its own firing time; the mapper moves it to the world frame with the body pose at that time
    (interpolated between the poses it received) and the LiDAR extrinsic ``T_BL``. Each frame's beams are cast
    from the LiDAR position at the middle of the frame. A frame waits until poses up to its last point have
    arrived; none is skipped, however slowly the mapper runs. The frames ready at a step are inserted in one
    call (:meth:`EsdfMap.insert_frames`: placed, cast in order, then one distance-field update), giving the
    same map as inserting them one at a time.
    """

    name = "esdf_mapper"

    def __init__(
        self,
        params: EsdfMapParams,
        T_BL: Transform | None = None,
        rate_hz: float = 100.0,
        state_topic: str | None = None,
        cloud_topic: str = Topics.POINT_CLOUD,
    ) -> None:
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

    def integrate(self, t: float, bus: BusView) -> None:
        state: Odometry
        for state in self._poses_sub.take():
            if not self._t or state.t > self._t[-1]:
                self._t.append(state.t)
                self._p.append(state.p_W)
                self._q.append(state.q_WB)
        self._waiting.extend(self._clouds_sub.take())
        ready: list[PointCloud] = []
        while (
            self._waiting
            and self._t
            and self._t[-1] >= self._waiting[0].t + float(np.max(self._waiting[0].dt, initial=0.0))
        ):
            ready.append(self._waiting.pop(0))
        if ready:
            self._insert(ready)
            bus.publish(Topics.ESDF_MAP, MapUpdate(self._last_stamp, self.map, self.frames))

    def _insert(self, clouds: list[PointCloud]) -> None:
        """Every frame that can be placed, in one call: placed, cast in order, then one field update."""
        frames = []
        for cloud in clouds:
            dt = np.asarray(cloud.dt, dtype=float)
            frames.append((cloud.points_L, cloud.t + dt, cloud.t + 0.5 * float(np.max(dt, initial=0.0))))
        poses = (np.asarray(self._t, dtype=float), np.asarray(self._p, dtype=float), np.asarray(self._q, dtype=float))
        self.map.insert_frames(frames, poses, self.T_BL)
        self.frames += len(clouds)
        self._last_stamp = clouds[-1].t
        # Keep only the poses a later frame can need.
        keep = max(0, int(np.searchsorted(self._t, clouds[-1].t, side="right")) - 1)
        del self._t[:keep], self._p[:keep], self._q[:keep]

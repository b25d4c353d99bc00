"""``LioEstimator``: :class:`LioCore` as a :class:`cufund.Estimator` (registry kind ``lio``).

Reads every IMU sample (a subscription to ``/sensors/imu``) and every LiDAR frame (``/sensors/lidar``), and
publishes the body ``Odometry`` on ``/estimator/odometry`` at IMU rate. A frame is processed once IMU samples
past its end have arrived (so its IMU factor and deskewing use measured motion, not extrapolation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cufund.core.components import Estimator
from cufund.core.messages import Odometry, OdometryDiagnostics, Topics

from .boundary import scan_frame
from .lio_core import LioCore, ScanDiagnostics
from .params import LioParams

__all__ = ["LioEstimator"]

_GAP_REPORT_S = 0.1
"""How often a LiDAR gap is reported [s]."""


class LioEstimator(Estimator):
    """LiDAR-inertial odometry on GTSAM (see :mod:`cufund.estimation.lio_core`)."""

    name = "lio"
    inputs: tuple[str, ...] = (Topics.IMU, Topics.POINT_CLOUD)

    def __init__(
        self,
        params: LioParams | dict | None = None,
        rate_hz: float | None = None,
        imu_topic: str = Topics.IMU,
        lidar_topic: str = Topics.POINT_CLOUD,
    ) -> None:
        if isinstance(params, dict):
            params = LioParams.from_dict(params)
        self.params = params or LioParams()
        self.rate_hz = float(rate_hz) if rate_hz is not None else float(self.params.imu.rate_hz)
        self.imu_topic, self.lidar_topic = imu_topic, lidar_topic
        self.inputs = (imu_topic, lidar_topic)
        self.extra_outputs = (Topics.ESTIMATOR_DIAGNOSTICS,)
        self.reset()

    def reset(self) -> None:
        self.core = LioCore(self.params)
        self._frames: list[tuple[float, Any, Any, float]] = []  # (start, dt, points, end)
        self._latest: Odometry | None = None
        self._imu_sub: Any = None
        self._lidar_sub: Any = None
        self._diagnosed = 0
        self._gap_reported = -math.inf

    def setup(self, bus) -> None:
        self._imu_sub = bus.subscribe(self.imu_topic)
        self._lidar_sub = bus.subscribe(self.lidar_topic)

    @property
    def diagnostics(self) -> list[ScanDiagnostics]:
        return self.core.diagnostics

    def estimate(self, t: float, bus) -> Odometry | None:
        self.feed(self._lidar_sub.take(), self._imu_sub.take())
        for d in self.core.diagnostics[self._diagnosed :]:  # one message per frame processed
            bus.publish(
                Topics.ESTIMATOR_DIAGNOSTICS,
                OdometryDiagnostics(
                    d.t,
                    d.points,
                    d.inliers,
                    d.iterations,
                    np.asarray(d.eigenvalues, dtype=float),
                    np.asarray(d.degenerate_directions, dtype=float).reshape(-1, 6),
                    d.time_ms,
                    d.cpu_ms,
                    d.skipped,
                    d.healthy,
                    d.reason,
                ),
            )
        self._diagnosed = len(self.core.diagnostics)
        self._report_gap(t, bus)
        return self._latest

    def _report_gap(self, t: float, bus) -> None:
        """Without LiDAR constraints for longer than health_max_lidar_gap_s, an unhealthy diagnostic every LiDAR
        period (no frame carries the news)."""
        gap = self.core.lidar_gap(t)
        if gap is None or gap <= self.params.health_max_lidar_gap_s or t - self._gap_reported < _GAP_REPORT_S:
            return
        self._gap_reported = t
        bus.publish(
            Topics.ESTIMATOR_DIAGNOSTICS,
            OdometryDiagnostics(
                t,
                0,
                0,
                0,
                np.zeros(0),
                np.zeros((0, 6)),
                0.0,
                0.0,
                "no LiDAR frame",
                False,
                f"no LiDAR constraint for {gap:.2f} s: IMU only",
            ),
        )

    def feed(self, clouds: list, imus: list) -> list[Odometry]:
        """Queues LiDAR frames, then integrates IMU samples in order, processing each queued frame as soon as a
        sample past its end arrives. Returns the IMU-rate outputs."""
        for cloud in clouds:
            start, dt, pts = scan_frame(cloud)
            end = start + (float(dt.max()) if len(dt) else 0.0)
            self._frames.append((start, dt, pts, end))
        self._frames.sort(key=lambda f: f[3])
        outputs = []
        for imu in imus:
            while self._frames and self._frames[0][3] < imu.t:
                start, dt, pts, _ = self._frames.pop(0)
                self.core.add_scan(start, dt, pts)
            out = self.core.add_imu(imu.t, imu.f_I, imu.w_I)
            if out is not None:
                self._latest = out
                outputs.append(out)
        return outputs

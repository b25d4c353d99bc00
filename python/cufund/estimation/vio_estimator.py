"""``VioEstimator``: :class:`VioCore` as a :class:`cufund.Estimator` (registry kind ``vio``).

Reads every IMU sample and both cameras' images (``CameraImage`` with identical stamps on the left and right
topics; with ``cameras: mono`` the left topic alone), pairs them by stamp, and publishes the body ``Odometry`` at IMU rate on the estimate topic, like the
LIO, so controllers, mappers and missions fly on it unchanged. A stereo frame is processed once an IMU sample
past its stamp has arrived. Per frame a ``VioDiagnostics`` goes to ``/estimator/diagnostics`` (tracked features,
inliers, parallax, landmarks, time offset, position sigma, time; ``skipped``, ``healthy`` and ``reason`` as the
LIO's), and while no frame adds a visual constraint for longer than ``health_max_gap_s``, an unhealthy one every
0.1 s.
"""

from __future__ import annotations

import math
from typing import Any

from cufund.core.components import Estimator
from cufund.core.messages import Odometry, Topics, VioDiagnostics

from .vio_core import VioCore
from .vio_params import VioParams

__all__ = ["VioEstimator"]

_GAP_REPORT_S = 0.1
_MAX_UNPAIRED = 20
"""Images kept waiting for their other half; older ones are dropped and counted."""


class VioEstimator(Estimator):
    """Stereo (or mono) visual-inertial odometry on GTSAM (see :mod:`cufund.estimation.vio_core`)."""

    name = "vio"

    def __init__(
        self,
        params: VioParams | dict | None = None,
        imu_topic: str = str(Topics.IMU),
        left_topic: str = "/sensors/cam0/image",
        right_topic: str | None = "/sensors/cam1/image",
    ) -> None:
        if isinstance(params, dict):
            params = VioParams.from_dict(params)
        self.params = params or VioParams()
        self.rate_hz = float(self.params.imu.rate_hz)
        if self.params.cameras == "mono":
            right_topic = None  # mono + IMU: the left camera alone
        elif right_topic is None:
            raise ValueError("VioEstimator: a stereo VIO needs right_topic (or params cameras: mono)")
        self.imu_topic, self.left_topic, self.right_topic = imu_topic, left_topic, right_topic
        self.inputs = (imu_topic, left_topic) if right_topic is None else (imu_topic, left_topic, right_topic)
        self.extra_outputs = (Topics.ESTIMATOR_DIAGNOSTICS,)
        self.reset()

    def reset(self) -> None:
        self.core = VioCore(self.params)
        self._left: dict[float, Any] = {}
        self._right: dict[float, Any] = {}
        self._frames: list[tuple[float, Any, Any]] = []
        self._latest: Odometry | None = None
        self._subs: tuple[Any, Any, Any | None] | None = None
        self._diagnosed = 0
        self._gap_reported = -math.inf
        self.unpaired_images = 0

    def setup(self, bus) -> None:
        right = bus.subscribe(self.right_topic) if self.right_topic is not None else None
        self._subs = (bus.subscribe(self.imu_topic), bus.subscribe(self.left_topic), right)

    def estimate(self, t: float, bus) -> Odometry | None:
        assert self._subs is not None
        imu, left, right = (s.take() if s is not None else [] for s in self._subs)
        self.feed(left, right, imu)
        for d in self.core.diagnostics[self._diagnosed :]:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, d)
        self._diagnosed = len(self.core.diagnostics)
        gap = self.core.visual_gap(t)
        if gap is not None and gap > self.params.health_max_gap_s and t - self._gap_reported >= _GAP_REPORT_S:
            self._gap_reported = t
            bus.publish(
                Topics.ESTIMATOR_DIAGNOSTICS,
                VioDiagnostics(
                    t=t,
                    tracked=0,
                    inliers=0,
                    stereo=0,
                    parallax_px=0.0,
                    keyframe=False,
                    landmarks=0,
                    time_ms=0.0,
                    cpu_ms=0.0,
                    time_offset_s=self.core.time_offset_s,
                    sigma_p_m=math.nan,
                    skipped="no camera frame",
                    healthy=False,
                    reason=f"no visual constraint for {gap:.2f} s: IMU only",
                ),
            )
        return self._latest

    def feed(self, left: list, right: list, imus: list) -> list[Odometry]:
        """Pairs images by stamp (mono: the left images alone), then integrates IMU samples in order, processing
        each frame once a sample past its stamp arrives. Returns the IMU-rate outputs."""
        if self.right_topic is None:
            self._frames += [(float(msg.t), msg.image, None) for msg in left]
            left = []
        for msg in left:
            self._left[float(msg.t)] = msg.image
        for msg in right:
            self._right[float(msg.t)] = msg.image
        for t in sorted(set(self._left) & set(self._right)):
            self._frames.append((t, self._left.pop(t), self._right.pop(t)))
        for side in (self._left, self._right):
            while len(side) > _MAX_UNPAIRED:
                del side[min(side)]
                self.unpaired_images += 1
        self._frames.sort(key=lambda f: f[0])
        outputs = []
        for imu in imus:
            while self._frames and self._frames[0][0] + self.params.time_offset_s < imu.t:
                self.core.add_frame(*self._frames.pop(0))
            out = self.core.add_imu(imu.t, imu.f_I, imu.w_I)
            if out is not None:
                self._latest = out
                outputs.append(out)
        return outputs

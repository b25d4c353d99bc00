"""The rate loop's body-rate input as PX4 has it: every gyro sample, rotated into the body frame and low-passed
(``IMU_GYRO_CUTOFF``), never the state estimate."""

from __future__ import annotations

import math

import numpy as np

from cufund.core.bus import BusView, Subscription
from cufund.core.messages import Imu, Topics
from cufund.geometry import quat_to_matrix

__all__ = ["GyroInput"]


class GyroInput:
    """Filters every :class:`~cufund.core.messages.Imu` sample on ``topic``: ``w_B = R_BI w_I`` through a first-order
    low-pass with cutoff ``cutoff_hz`` (0: no filter), stepped at each sample's own interval."""

    def __init__(
        self,
        q_BI: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
        cutoff_hz: float = 40.0,
        topic: str = Topics.IMU,
    ) -> None:
        if not (math.isfinite(cutoff_hz) and float(cutoff_hz) >= 0):
            raise ValueError(f"cutoff_hz must be a finite number >= 0 [Hz], got {cutoff_hz!r}")
        self.topic = topic
        self.cutoff_hz = float(cutoff_hz)
        self._R_BI = quat_to_matrix(np.asarray(q_BI, dtype=float))
        self._identity = bool(np.array_equal(self._R_BI, np.eye(3)))
        self._sub: Subscription | None = None
        self.reset()

    def reset(self) -> None:
        self.w_B: np.ndarray | None = None
        """The filtered body rate [rad/s] (None before the first sample)."""
        self._t: float | None = None

    def setup(self, bus: BusView) -> None:
        self._sub = bus.subscribe(self.topic)

    def update(self) -> np.ndarray | None:
        """Takes the samples that arrived since the last call; returns the filtered body rate."""
        assert self._sub is not None, "GyroInput.setup(bus) must run first"
        m: Imu
        for m in self._sub.take():
            w = m.w_I if self._identity else self._R_BI @ m.w_I
            if self.w_B is None or self.cutoff_hz == 0 or self._t is None:
                self.w_B = np.array(w, dtype=float)
            else:
                dt = m.t - self._t
                if dt > 0:
                    a = 1.0 - math.exp(-2.0 * math.pi * self.cutoff_hz * dt)
                    self.w_B = self.w_B + a * (w - self.w_B)
            self._t = m.t
        return self.w_B

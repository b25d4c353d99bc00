"""The interface of a fault on what a sensor publishes (the plant's faults are in :mod:`.plant`)."""

from __future__ import annotations

import logging
from typing import Any, ClassVar

import numpy as np

_log = logging.getLogger("cufund.faults")

__all__ = ["FaultRun", "SensorFault"]


class FaultRun:
    """One fault during a run: its seeded random stream, the sensor's params and the fault's own state."""

    def __init__(self, fault: SensorFault, seed: int, sensor_params: Any = None) -> None:
        self.fault, self.seed, self.sensor_params = fault, seed, sensor_params
        self.reset()

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.state = self.fault.start(self)
        self.affected = 0
        """Messages dropped or altered so far in this run."""

    def apply(self, now: float, msg: Any) -> Any:
        out = self.fault.apply(now, msg, self)
        if out is not msg:
            if not self.affected:
                _log.info("fault %s acts from t = %.6f s: %r", self.fault.kind, now, self.fault)
            self.affected += 1
        return out


class SensorFault:
    """A fault acting on the messages one sensor publishes (a mixin of the frozen params dataclasses)."""

    kind: ClassVar[str]
    """The fault's name under ``faults:``."""
    sensor_type: ClassVar[str]
    """The type of sensor it acts on (``imu``, ``lidar``, ``gps``, ...)."""
    sensor: str
    """The sensor's name under ``sensors`` ('' : the only one of its type)."""

    def start(self, run: FaultRun) -> Any:
        """The fault's state at the start of a run (drawn from ``run.rng`` where it is random)."""
        return None

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        """``msg`` as the faulty sensor publishes it at simulated time ``now`` (None: not at all); ``msg`` itself
        when the fault does not act on it."""
        raise NotImplementedError

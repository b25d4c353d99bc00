"""The simulator component every model-based sensor (IMU, magnetometer, barometer, GPS) is."""

from __future__ import annotations

from typing import Any

from cufund.core.components import Sensor


class ModelSensor(Sensor):
    """A :class:`~cufund.Sensor` around a measurement model with its own seeded stream: it runs at the part's
    rate, publishes on ``topic`` and restarts the model's stream at the start of every run."""

    def __init__(self, model: Any, rate_hz: float, topic: str) -> None:
        self.model = model
        self.rate_hz = rate_hz
        self.topic = topic

    def reset(self) -> None:
        self.model.reset()

"""IMU faults: a bias step (the sensor's full-scale saturation is a term of the IMU model itself,
:attr:`cufund.sensors.ImuParams.saturation`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.messages import Imu

from .base import FaultRun, SensorFault
from .common import check_sensor, check_time, check_vector

__all__ = ["ImuBiasStep"]


@dataclass(frozen=True)
class ImuBiasStep(SensorFault):
    """The IMU's biases jump at ``t_start`` (measurement stamp) and stay: the accelerometer reads ``accel`` more
    and the gyroscope ``gyro`` more, in the IMU's own frame."""

    t_start: float
    """When the biases jump (measurement stamp) [s]."""
    accel: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Accelerometer bias step, IMU frame [m/s^2]."""
    gyro: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Gyroscope bias step, IMU frame [rad/s]."""
    sensor: str = ""
    """The IMU's name under ``sensors`` ('' : the only IMU)."""

    kind = "imu_bias_step"
    sensor_type = "imu"

    def __post_init__(self) -> None:
        w = f"faults.{self.kind}"
        object.__setattr__(self, "t_start", check_time(f"{w}.t_start", self.t_start))
        object.__setattr__(self, "accel", check_vector(f"{w}.accel", self.accel, 100.0, " [m/s^2]"))
        object.__setattr__(self, "gyro", check_vector(f"{w}.gyro", self.gyro, 10.0, " [rad/s]"))
        check_sensor(f"{w}.sensor", self.sensor)

    def apply(self, now: float, msg: Any, run: FaultRun) -> Any:
        if msg.t < self.t_start:
            return msg
        return Imu(msg.t, msg.f_I + np.asarray(self.accel), msg.w_I + np.asarray(self.gyro))

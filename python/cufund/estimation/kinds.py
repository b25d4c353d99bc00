"""The built-in estimator kinds of scenarios."""

from __future__ import annotations

from typing import Any

from ..registry import Kind, register
from .imu_propagator import ImuPropagator, ImuPropagatorParams


def _imu_propagator(p: ImuPropagatorParams, ctx: Any) -> list[Any]:
    _, imu = ctx.sensor_of_type("imu", "", "estimator")
    _, pose = ctx.sensor_of_type("pose", "", "estimator")
    imu_params = ctx.imu_params()
    return [ImuPropagator(imu_params.rate_hz, ctx.vehicle.gravity, imu_params.q_BI, p, imu.topic, pose.topic)]


register(Kind("estimator", "imu_propagator", ImuPropagatorParams, _imu_propagator, None,
              "IMU-rate odometry between slow pose corrections (sensors: an IMU and a pose source)"))

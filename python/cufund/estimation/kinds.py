"""The built-in estimator kinds of scenarios."""

from __future__ import annotations

import dataclasses
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError
from cufund.core.registry import Kind, register

from .imu_propagator import ImuPropagator, ImuPropagatorParams
from .params import LioParams

_FROM_SCENARIO = {
    "imu": "sensors.<imu> (its kind and T_BI)",
    "T_BL": "sensors.<lidar>.T_BL",
    "p_WB0": "start_p_W",
    "gravity": "vehicle",
}


def _imu_propagator(p: ImuPropagatorParams, ctx: BuildContext) -> list[Any]:
    _, imu = ctx.sensor_of_type("imu", "", "estimator")
    _, pose = ctx.sensor_of_type("pose", "", "estimator")
    imu_params = ctx.imu_params()
    return [ImuPropagator(imu_params.rate_hz, ctx.vehicle.gravity, imu_params.q_BI, p, imu.topic, pose.topic)]


register(
    Kind(
        "estimator",
        "imu_propagator",
        ImuPropagatorParams,
        _imu_propagator,
        None,
        "IMU-rate odometry between slow pose corrections (sensors: an IMU and a pose source)",
    )
)


def lio_params(p: LioParams, ctx: BuildContext) -> tuple[LioParams, Any, Any]:
    """The LIO's params completed from the scenario (IMU part and mounting, LiDAR extrinsic, pad position,
    gravity: each given once, in the scenario), with the IMU and LiDAR specs."""
    default = LioParams()
    for name, source in _FROM_SCENARIO.items():
        if getattr(p, name) != getattr(default, name):
            raise ConfigError(f"estimator.{name}: the LIO takes it from the scenario ({source}); give it once there")
    _, imu = ctx.sensor_of_type("imu", "", "estimator")
    _, lidar = ctx.sensor_of_type("lidar", "", "estimator")
    start = ctx.config.start_p_W or (ctx.config.trajectory.waypoints[0][0], ctx.config.trajectory.waypoints[0][1], 0.0)
    params = dataclasses.replace(
        p, imu=ctx.imu_params(), T_BL=lidar.extrinsic or default.T_BL, p_WB0=tuple(start), gravity=ctx.vehicle.gravity
    )
    return params, imu, lidar


def _lio(p: LioParams, ctx: BuildContext) -> list[Any]:
    from .lio_estimator import LioEstimator  # GTSAM loads only when a scenario uses the LIO

    params, imu, lidar = lio_params(p, ctx)
    return [LioEstimator(params, imu_topic=imu.topic, lidar_topic=lidar.topic)]


register(
    Kind(
        "estimator",
        "lio",
        LioParams,
        _lio,
        None,
        "LiDAR-inertial odometry on GTSAM (sensors: an IMU and a LiDAR; the pad gives origin and yaw, the IMU roll, pitch and biases)",
    )
)

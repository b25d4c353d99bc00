"""The built-in estimator kinds of scenarios."""

from __future__ import annotations

import dataclasses
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError
from cufund.core.registry import Kind, register

from .imu_propagator import ImuPropagator, ImuPropagatorParams
from .params import LioParams
from .vio_params import VioCamera, VioParams

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


def _pad(pad_yaw: float, default_yaw: float, ctx: BuildContext) -> tuple[tuple[float, float, float], float]:
    """The pad an odometry starts on, as the scenario states it: its position (``start_p_W``, else below the first
    waypoint) and heading (an estimator's own ``pad_yaw`` when given, else ``start_yaw``, where the vehicle stands)."""
    c = ctx.config
    start = c.start_p_W or (c.trajectory.waypoints[0][0], c.trajectory.waypoints[0][1], 0.0)
    return tuple(start), (pad_yaw if pad_yaw != default_yaw else float(c.start_yaw))


def lio_params(p: LioParams, ctx: BuildContext) -> tuple[LioParams, Any, Any]:
    """The LIO's params completed from the scenario (IMU part and mounting, LiDAR extrinsic, pad position,
    gravity: each given once, in the scenario), with the IMU and LiDAR specs."""
    default = LioParams()
    for name, source in _FROM_SCENARIO.items():
        if getattr(p, name) != getattr(default, name):
            raise ConfigError(f"estimator.{name}: the LIO takes it from the scenario ({source}); give it once there")
    _, imu = ctx.sensor_of_type("imu", "", "estimator")
    _, lidar = ctx.sensor_of_type("lidar", "", "estimator")
    start, pad_yaw = _pad(p.pad_yaw, default.pad_yaw, ctx)
    params = dataclasses.replace(
        p,
        imu=ctx.imu_params(),
        T_BL=lidar.extrinsic or default.T_BL,
        p_WB0=start,
        pad_yaw=pad_yaw,
        gravity=ctx.vehicle.gravity,
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


def vio_params(p: VioParams, ctx: BuildContext) -> tuple[VioParams, Any, list[str]]:
    """The VIO's params completed from the scenario: the IMU part and mounting, the stereo rig's calibration
    (the ``stereo_camera`` sensor's stated cameras, never the renderer's truth), the pad and gravity. Returns
    (params, IMU spec, the two camera topics)."""
    default = VioParams()
    for name, source in (
        ("imu", "sensors.<imu>"),
        ("cam0", "sensors.<stereo_camera>"),
        ("cam1", "sensors.<stereo_camera>"),
        ("p_WB0", "start_p_W"),
        ("gravity", "vehicle"),
    ):
        if getattr(p, name) != getattr(default, name):
            raise ConfigError(f"estimator.{name}: the VIO takes it from the scenario ({source}); give it once there")
    _, imu = ctx.sensor_of_type("imu", "", "estimator")
    if not any(s is not None and s.sensor_type == "stereo_camera" for s in (ctx.config.sensors or {}).values()):
        raise ConfigError(
            "estimator: the VIO needs a stereo_camera sensor (this scenario has none); add one, e.g. "
            "--set sensors.stereo.kind=stereo_camera --set sensors.stereo.hw_sync=true"
        )
    _, cam = ctx.sensor_of_type("stereo_camera", "", "estimator")
    cams = cam.params.cameras(ctx.base_dir, None)
    if len(cams) < 2:
        raise ConfigError(f"estimator: the VIO needs a stereo pair, sensors.<stereo_camera> has {len(cams)} camera(s)")
    rig = []
    for c in cams[:2]:
        k = c.intrinsics
        if getattr(k, "distortion_model", "radtan") != "radtan":
            raise ConfigError(f"estimator: the VIO reads radtan cameras only, {c.name} is {k.distortion_model}")
        d = tuple(k.distortion) + (0.0,) * (5 - len(k.distortion))
        rig.append(VioCamera(k.width, k.height, k.fx, k.fy, k.cx, k.cy, d, c.T_BC))
    shifts = {c.timeshift_s for c in cams[:2]}
    if len(shifts) != 1:
        raise ConfigError("estimator: the VIO needs both stereo cameras on one clock (equal timeshift_cam_imu)")
    start, pad_yaw = _pad(p.pad_yaw, default.pad_yaw, ctx)
    topics = list(cam.params.camera_topics(len(cams)))
    params = dataclasses.replace(
        p,
        imu=ctx.imu_params(),
        cam0=rig[0],
        cam1=rig[1],
        p_WB0=start,
        pad_yaw=pad_yaw,
        gravity=ctx.vehicle.gravity,
        time_offset_s=p.time_offset_s + shifts.pop(),
    )
    return params, imu, topics[:2]


def _vio(p: VioParams, ctx: BuildContext) -> list[Any]:
    from .vio_estimator import VioEstimator  # GTSAM and OpenCV load only when a scenario uses the VIO

    params, imu, topics = vio_params(p, ctx)
    return [VioEstimator(params, imu_topic=imu.topic, left_topic=topics[0], right_topic=topics[1])]


register(
    Kind(
        "estimator",
        "vio",
        VioParams,
        _vio,
        None,
        "Stereo visual-inertial odometry on GTSAM (sensors: an IMU and a stereo_camera; the pad gives origin and yaw, the IMU roll, pitch and gyro bias)",
    )
)

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


@dataclasses.dataclass(frozen=True)
class _DefaultRig:
    """The part the ``vio`` kind mounts on a scenario without a ``stereo_camera`` (a ``PartView``): the
    ``stereo_camera`` kind's default rig (640x480 grey at 20 Hz, 11 cm baseline, 0.1 m ahead of the body origin,
    looking along body x), triggered on the IMU's samples."""

    params: Any
    kind: str = "stereo_camera"
    latency_s: float = 0.0
    phase_s: float = 0.0
    topic: Any = None
    extrinsic: Any = None
    sensor_type: str | None = "stereo_camera"


DEFAULT_RIG_NAME = "stereo"
"""``sensors.<this>``: where the default rig is built (its seeds and truth reads are that sensor's)."""


def _has_rig(ctx: BuildContext) -> bool:
    return any(s is not None and s.sensor_type == "stereo_camera" for s in (ctx.config.sensors or {}).values())


def default_rig() -> _DefaultRig:
    from cufund.sensors.kinds import StereoCameraParams

    return _DefaultRig(StereoCameraParams(hw_sync=True))


def vio_params(p: VioParams, ctx: BuildContext) -> tuple[VioParams, Any, list[str]]:
    """The VIO's params completed from the scenario: the IMU part and mounting, the stereo rig's calibration
    (the ``stereo_camera`` sensor's stated cameras, never the renderer's truth; on a scenario without one, the
    default rig's, which the ``vio`` kind mounts there), the pad and gravity. Returns (params, IMU spec, the camera
    topics: two, or one for ``mono``). ``cufund odometry`` calls it on a log's recorded scenario."""
    default = VioParams()
    mono = p.cameras == "mono"
    for name, source in (
        ("imu", "sensors.<imu>"),
        ("cam0", "sensors.<stereo_camera>"),
        ("cam1", "sensors.<stereo_camera>"),
        ("p_WB0", "start_p_W"),
        ("gravity", "vehicle"),
    ):
        if getattr(p, name) != getattr(default, name) and not (mono and name == "cam1"):
            raise ConfigError(f"estimator.{name}: the VIO takes it from the scenario ({source}); give it once there")
    _, imu = ctx.sensor_of_type("imu", "", "estimator")
    rig_part = ctx.sensor_of_type("stereo_camera", "", "estimator")[1] if _has_rig(ctx) else default_rig()
    cams = rig_part.params.cameras(ctx.base_dir, None)
    if len(cams) < (1 if mono else 2):
        raise ConfigError(
            f"estimator: the VIO needs a stereo pair (or cameras: mono), sensors.<stereo_camera> has {len(cams)} "
            "camera(s)"
        )
    used = cams[:1] if mono else cams[:2]
    rig = []
    for c in used:
        k = c.intrinsics
        if getattr(k, "distortion_model", "radtan") != "radtan":
            raise ConfigError(f"estimator: the VIO reads radtan cameras only, {c.name} is {k.distortion_model}")
        d = tuple(k.distortion) + (0.0,) * (5 - len(k.distortion))
        rig.append(VioCamera(k.width, k.height, k.fx, k.fy, k.cx, k.cy, d, c.T_BC))
    shifts = {c.timeshift_s for c in used}
    if len(shifts) != 1:
        raise ConfigError("estimator: the VIO needs both stereo cameras on one clock (equal timeshift_cam_imu)")
    start, pad_yaw = _pad(p.pad_yaw, default.pad_yaw, ctx)
    topics = list(rig_part.params.camera_topics(len(cams)))
    params = dataclasses.replace(
        p,
        imu=ctx.imu_params(),
        cam0=rig[0],
        cam1=None if mono else rig[1],
        p_WB0=start,
        pad_yaw=pad_yaw,
        gravity=ctx.vehicle.gravity,
        time_offset_s=p.time_offset_s + shifts.pop(),
    )
    return params, imu, topics[: len(used)]


def _vio(p: VioParams, ctx: BuildContext) -> list[Any]:
    """The VIO on the scenario's stereo_camera; on a scenario without one (the tunnel: a LiDAR for the frame
    detector), on the default rig (:func:`default_rig`), built here as ``sensors.stereo``."""
    from .vio_estimator import VioEstimator  # GTSAM and OpenCV load only when a scenario uses the VIO

    parts: list[Any] = []
    if not _has_rig(ctx):
        if DEFAULT_RIG_NAME in (ctx.config.sensors or {}):
            raise ConfigError(
                f"estimator: the VIO needs a stereo_camera sensor; sensors.{DEFAULT_RIG_NAME} is a "
                f"{ctx.config.sensors[DEFAULT_RIG_NAME].sensor_type}: add a stereo_camera under another name"
            )
        parts = ctx.build("sensor", default_rig(), f"sensors.{DEFAULT_RIG_NAME}")
    params, imu, topics = vio_params(p, ctx)
    return [
        *parts,
        VioEstimator(
            params, imu_topic=imu.topic, left_topic=topics[0], right_topic=topics[1] if len(topics) > 1 else None
        ),
    ]


register(
    Kind(
        "estimator",
        "vio",
        VioParams,
        _vio,
        None,
        "Stereo (or cameras: mono) visual-inertial odometry on GTSAM (sensors: an IMU and a stereo_camera, else the default rig is mounted; the pad gives origin and yaw, the IMU roll, pitch and gyro bias)",
    )
)

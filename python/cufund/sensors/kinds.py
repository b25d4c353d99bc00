"""The built-in sensor kinds of scenarios (``sensors: {NAME: {kind: ..., ...}}``).

Every sensor entry takes, besides its kind's params: ``topic`` (default ``/sensors/NAME``), ``latency_s``,
``phase_s`` and, for mounted sensors, its extrinsic given once — ``T_BI`` (IMU), ``T_BL`` (LiDAR), ``T_BC``
(camera) as ``{p: [x, y, z], q: [w, x, y, z]}`` (sensor frame to body). Each sensor's random stream is derived
from the scenario seed and the sensor's name.

Each sensor type is registered once here (:class:`cufund.core.registry.SensorType`: the message its topic carries
and its mounting key); the scenario schema looks both up from the registry. A new sensor type is its own module
plus one registration of its type and kinds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most, check_real_fields
from cufund.core.messages import AirPressure, CameraImage, GpsFix, Imu, MagneticField, PointCloud, Pose
from cufund.core.registry import Kind, SensorType, register

from .barometer import BAROMETER_PRESETS, BarometerParams, BarometerSensor
from .camera import DepthCamera, RgbCamera, d435_depth, d435_rgb
from .camera_component import CameraComponent
from .gps import GPS_PRESETS, GpsParams, GpsSensor
from .imu import IMU_PRESETS, ImuParams, ImuSensor
from .lidar import Lidar, LidarParams
from .lidar_component import LidarComponent
from .magnetometer import MagnetometerParams, MagnetometerSensor
from .patterns import ScanPattern, avia, mid360, os1_64, vlp16
from .pose_sensor import PoseSensor, PoseSensorParams

for _type in (
    SensorType("imu", Imu, "T_BI", "accelerometer and gyroscope, in the IMU frame I"),
    SensorType("magnetometer", MagneticField, None, "magnetic field along the body axes"),
    SensorType("barometer", AirPressure, None, "static pressure and pressure altitude"),
    SensorType("gps", GpsFix, None, "GNSS fix (position, velocity) of the vehicle"),
    SensorType("lidar", PointCloud, "T_BL", "ray-traced point clouds, in the LiDAR frame L"),
    SensorType("camera", CameraImage, "T_BC", "ray-traced depth or colour images, camera frame C"),
    SensorType("pose", Pose, None, "a pose source (motion capture, a slow odometry): position and attitude"),
):
    register(_type)

_PATTERNS: dict[str, Callable[[], ScanPattern]] = {"mid360": mid360, "os1_64": os1_64, "vlp16": vlp16, "avia": avia}


def _imu(params: ImuParams, ctx: BuildContext) -> list[Any]:
    T = ctx.part.extrinsic
    if T is not None:
        if params.p_BI != (0.0, 0.0, 0.0) or params.q_BI != (1.0, 0.0, 0.0, 0.0):
            raise ConfigError(f"{ctx.where}: give the IMU's mounting once, as T_BI or as p_BI/q_BI, not both")
        params = dataclasses.replace(params, p_BI=T.t, q_BI=T.q)
    # the simulated part after calibration, with the realism profile's drawn errors (flight software reads the
    # part as stated through ctx.imu_params()); its vibration follows the simulated plant's hover rotor speed
    plant = ctx.realism.simulated_vehicle(ctx.vehicle)
    params = ctx.realism.simulated_imu(ctx.where, params, plant.hover_rotor_speed)
    return [ImuSensor(params, ctx.seed, ctx.vehicle.gravity, ctx.part.topic)]


for _name, _preset in IMU_PRESETS.items():
    register(
        Kind(
            "sensor",
            "ideal_imu" if _name == "ideal" else _name,
            ImuParams,
            _imu,
            _preset,
            f"IMU, {_name} preset (cufund.sensors.ImuParams)",
            sensor_type="imu",
        )
    )
register(
    Kind(
        "sensor",
        "magnetometer",
        MagnetometerParams,
        lambda p, ctx: [MagnetometerSensor(p, ctx.seed, ctx.part.topic)],
        None,
        "magnetometer (cufund.sensors.MagnetometerParams)",
        sensor_type="magnetometer",
    )
)
for _name, _baro_preset in BAROMETER_PRESETS.items():
    register(
        Kind(
            "sensor",
            "ideal_barometer" if _name == "ideal" else _name,
            BarometerParams,
            lambda p, ctx: [BarometerSensor(p, ctx.seed, ctx.part.topic)],
            _baro_preset,
            f"barometer, {_name} preset (cufund.sensors.BarometerParams)",
            sensor_type="barometer",
        )
    )
for _name, _gps_preset in GPS_PRESETS.items():
    register(
        Kind(
            "sensor",
            "ideal_gps" if _name == "ideal" else _name,
            GpsParams,
            lambda p, ctx: [GpsSensor(p, ctx.seed, ctx.part.topic)],
            _gps_preset,
            f"GNSS receiver, {_name} preset (cufund.sensors.GpsParams)",
            sensor_type="gps",
        )
    )
register(
    Kind(
        "sensor",
        "pose",
        PoseSensorParams,
        lambda p, ctx: [PoseSensor(p, ctx.seed, ctx.part.topic)],
        None,
        "pose source (motion capture or a slow odometry): Pose (no velocity) at rate_hz with noise",
        sensor_type="pose",
    )
)


@dataclass(frozen=True)
class LidarSensorParams:
    """A ray-traced LiDAR: its scan pattern and range model (:class:`cufund.sensors.LidarParams`)."""

    pattern: str = "mid360"
    """Scan pattern: mid360, os1_64, vlp16 or avia."""
    pose_rate_hz: float = 100.0
    """How often the true pose is sampled for each frame's motion distortion [Hz] (a multiple of the frame
    rate)."""
    range_min: float = 0.1
    """Blind zone [m]."""
    range_max: float = 40.0
    """Largest range [m]."""
    range_noise_std: float = 0.02
    """Range noise, 1 sigma [m]."""
    dropout: float = 0.0
    """Probability that a return is lost, in [0, 1)."""
    nthreads: int = 0
    """Ray-casting threads (0: the pool's default)."""

    def __post_init__(self) -> None:
        if self.pattern not in _PATTERNS:
            raise ConfigError(f"LidarSensorParams.pattern must be one of {', '.join(_PATTERNS)}, got {self.pattern!r}")
        check_real_fields(
            self, "LidarSensorParams", names=("pose_rate_hz", "range_min", "range_max", "range_noise_std", "dropout")
        )
        check_at_most(self, "LidarSensorParams", pose_rate_hz=1e4, range_max=1e4)
        if isinstance(self.nthreads, bool) or not isinstance(self.nthreads, int) or self.nthreads < 0:
            raise ConfigError(f"LidarSensorParams.nthreads must be an integer >= 0, got {self.nthreads!r}")
        LidarParams(
            range_min=self.range_min,
            range_max=self.range_max,
            range_noise_std=self.range_noise_std,
            dropout=self.dropout,
        )  # validates the range model


def _lidar(p: LidarSensorParams, ctx: BuildContext) -> list[Any]:
    world = ctx.require_world()
    params = LidarParams(
        range_min=p.range_min,
        range_max=p.range_max,
        range_noise_std=p.range_noise_std,
        dropout=p.dropout,
        seed=ctx.seed,
        nthreads=p.nthreads,
    )
    # the simulated LiDAR: the realism profile's range model and clock offset, mounted where it truly is (flight
    # software reads the stated extrinsic from the scenario)
    lidar = Lidar(
        _PATTERNS[p.pattern](),
        ctx.realism.simulated_lidar(ctx.where, params),
        ctx.realism.simulated_extrinsic(ctx.where, ctx.part.extrinsic),
    )
    try:
        return [LidarComponent(lidar, world, ctx.part.topic, p.pose_rate_hz)]
    except ValueError as e:
        raise ConfigError(f"{ctx.where}.pose_rate_hz: {e}") from None


_LIDARS = {
    "mid360": LidarSensorParams(),
    "os1_64": LidarSensorParams("os1_64", range_min=0.3, range_max=120.0, range_noise_std=0.03),
    "vlp16": LidarSensorParams("vlp16", range_min=0.5, range_max=100.0, range_noise_std=0.03),
    "avia": LidarSensorParams("avia", range_min=0.5, range_max=190.0, range_noise_std=0.02),
}


def _fixed(p: LidarSensorParams) -> Callable[[], LidarSensorParams]:
    return lambda: p


for _name, _p in _LIDARS.items():
    register(
        Kind(
            "sensor",
            _name,
            LidarSensorParams,
            _lidar,
            _fixed(_p),
            f"LiDAR, {_name} scan pattern and range model",
            sensor_type="lidar",
        )
    )


@dataclass(frozen=True)
class CameraSensorParams:
    """A ray-traced pinhole camera (Intel RealSense D435 intrinsics)."""

    rate_hz: float = 30.0
    """Frames per second [Hz]."""
    depth_min: float = 0.1
    """Depth camera: nearest depth reported [m]."""
    depth_max: float = 10.0
    """Depth camera: farthest depth reported [m]."""
    noise_coeff: float = 0.0
    """Depth camera: noise sigma = noise_coeff * z^2 [1/m]."""
    nthreads: int = 0
    """Ray-casting threads (0: the pool's default)."""

    def __post_init__(self) -> None:
        check_real_fields(self, "CameraSensorParams", names=("rate_hz", "depth_min", "depth_max", "noise_coeff"))
        if self.rate_hz <= 0:
            raise ConfigError(f"CameraSensorParams.rate_hz must be > 0 [Hz], got {self.rate_hz!r}")
        check_at_most(self, "CameraSensorParams", rate_hz=1e3, depth_max=1e4)


def _camera(depth: bool) -> Any:
    def build(p: CameraSensorParams, ctx: BuildContext) -> list[Any]:
        world = ctx.require_world()
        T_BC = ctx.realism.simulated_extrinsic(ctx.where, ctx.part.extrinsic)  # where it truly is
        try:
            cam = (
                DepthCamera(d435_depth(), T_BC, p.depth_min, p.depth_max, p.noise_coeff, ctx.seed, p.nthreads)
                if depth
                else RgbCamera(d435_rgb(), T_BC, nthreads=p.nthreads)
            )
        except ValueError as e:
            raise ConfigError(f"{ctx.where}: {e}") from None
        return [CameraComponent(cam, world, ctx.part.topic, p.rate_hz)]

    return build


register(
    Kind(
        "sensor",
        "d435_depth",
        CameraSensorParams,
        _camera(True),
        None,
        "depth camera (D435 depth intrinsics)",
        sensor_type="camera",
    )
)
register(
    Kind(
        "sensor",
        "d435_rgb",
        CameraSensorParams,
        _camera(False),
        None,
        "RGB camera (D435 colour intrinsics)",
        sensor_type="camera",
    )
)

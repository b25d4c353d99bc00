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

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most, check_real_fields
from cufund.core.messages import AirPressure, CameraImage, GpsFix, Imu, MagneticField, PointCloud, Pose
from cufund.core.registry import Kind, SensorType, register
from cufund.geometry import Transform

from .barometer import BAROMETER_PRESETS, BarometerParams, BarometerSensor
from .camera import DepthCamera, RgbCamera, d435_depth, d435_rgb
from .camera_component import CameraComponent, CameraRigComponent
from .camera_models import CameraCalibration, CameraIntrinsics
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


def _default_intrinsics() -> CameraIntrinsics:
    """A 640x480 global-shutter VI-sensor camera (≈ 77° x 62° field of view)."""
    return CameraIntrinsics(640, 480, 400.0, 400.0, 319.5, 239.5)


@dataclass(frozen=True)
class StereoCameraParams:
    """A rig of image cameras triggered together (a stereo pair by default; more with one mounting each), rendered
    with materials, sun light and shadows. Each camera publishes on its own topic (``/sensors/cam<i>/image``), all
    frames of a trigger with the same stamp. Consumers (a VIO) read the rig's calibration at build time from
    :meth:`cameras` of the scenario's sensor spec."""

    rate_hz: float = 20.0
    """Frames per second [Hz]."""
    intrinsics: CameraIntrinsics = dataclasses.field(default_factory=_default_intrinsics)
    """Every camera's intrinsics: {width, height, fx, fy, cx, cy, distortion, distortion_model}."""
    baseline: float = 0.11
    """Stereo baseline [m] when ``extrinsics`` is not given: cam0 (left) at y = +baseline/2, cam1 at -baseline/2, 0.1 m
    ahead of the body origin, both looking along body x."""
    extrinsics: tuple[Transform, ...] = ()
    """Each camera's mounting T_BC {p: [x, y, z], q: [w, x, y, z]} (camera frame C, FLU, in the body frame);
    overrides ``baseline``; any number of cameras. (The rig has no single ``T_BC`` key.)"""
    calibration: str = ""
    """A Kalibr camchain YAML (relative to the scenario file): its cameras replace intrinsics and extrinsics."""
    color: str = "gray"
    """gray: (H, W) uint8 images; rgb: (H, W, 3) uint8."""
    shutter: str = "global"
    """global or rolling (row r exposed (r - (H-1)/2) x line_time_s after the stamp)."""
    line_time_s: float = 3e-5
    """Rolling shutter: time between rows [s]."""
    exposure_s: float = 0.0
    """Exposure time [s]; > 0 blurs the image along the motion over it (blur_samples sub-frames)."""
    blur_samples: int = 5
    """Sub-frames per image when exposure_s > 0."""
    full_well_e: float = 0.0
    """Shot noise: electrons at full scale (0: none; e.g. 10000)."""
    read_noise_dn: float = 0.0
    """Read noise, 1 sigma [8-bit DN]."""
    shadows: bool = True
    """Hard shadows of the sun (one shadow ray per pixel)."""
    ambient: float = 0.35
    """Ambient share of the light, in [0, 1]."""
    light_W: tuple[float, float, float] = (0.3, 0.2, 1.0)
    """Direction to the sun in the world frame."""
    hw_sync: bool = False
    """Trigger frames on IMU sample times (the IMU's phase; its rate a multiple of rate_hz), as a VI-sensor."""
    topics: tuple[str, ...] = ()
    """Each camera's topic (default /sensors/cam0/image, /sensors/cam1/image, ...)."""
    nthreads: int = 0
    """Ray-casting threads (0: the pool's default)."""

    def __post_init__(self) -> None:
        from cufund.core.config import nested

        from .camera_models import _transform

        W = "StereoCameraParams"
        check_real_fields(
            self,
            W,
            names=("rate_hz", "baseline", "line_time_s", "exposure_s", "full_well_e", "read_noise_dn", "ambient"),
        )
        if self.rate_hz <= 0:
            raise ConfigError(f"{W}.rate_hz must be > 0 [Hz], got {self.rate_hz!r}")
        check_at_most(self, W, rate_hz=1e3, baseline=100.0, line_time_s=1e-2, exposure_s=1.0, ambient=1.0)
        try:
            object.__setattr__(self, "intrinsics", nested(CameraIntrinsics, self.intrinsics, f"{W}.intrinsics"))
        except ValueError as e:
            raise ConfigError(f"{W}.intrinsics: {e}") from None
        ext = self.extrinsics
        if isinstance(ext, (str, bytes, dict)) or not hasattr(ext, "__len__"):
            raise ConfigError(f"{W}.extrinsics must be a list of {{p, q}} mountings T_BC, one per camera, got {ext!r}")
        try:
            object.__setattr__(
                self, "extrinsics", tuple(_transform(T, f"{W}.extrinsics[{i}]") for i, T in enumerate(ext))
            )
        except ValueError as e:
            raise ConfigError(str(e)) from None
        for name, allowed in (("color", ("gray", "rgb")), ("shutter", ("global", "rolling"))):
            if getattr(self, name) not in allowed:
                raise ConfigError(f"{W}.{name} must be one of {', '.join(allowed)}, got {getattr(self, name)!r}")
        for name in ("shadows", "hw_sync"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{W}.{name} must be true or false, got {getattr(self, name)!r}")
        if not isinstance(self.calibration, str):
            raise ConfigError(f"{W}.calibration must be a file name, got {self.calibration!r}")
        b = self.blur_samples
        if isinstance(b, bool) or not isinstance(b, int) or not 1 <= b <= 64:
            raise ConfigError(f"{W}.blur_samples must be an integer in [1, 64], got {b!r}")
        if isinstance(self.nthreads, bool) or not isinstance(self.nthreads, int) or self.nthreads < 0:
            raise ConfigError(f"{W}.nthreads must be an integer >= 0, got {self.nthreads!r}")
        light = np.asarray(self.light_W, dtype=float) if not isinstance(self.light_W, str) else np.zeros(0)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or not np.any(light):
            raise ConfigError(f"{W}.light_W must be a non-zero 3-vector, got {self.light_W!r}")
        object.__setattr__(self, "light_W", tuple(float(x) for x in light))
        if isinstance(self.topics, (str, bytes)) or not all(isinstance(t, str) for t in self.topics):
            raise ConfigError(f"{W}.topics must be a list of topic names, got {self.topics!r}")
        object.__setattr__(self, "topics", tuple(self.topics))
        n = len(self.extrinsics) or 2
        if self.topics and not self.calibration and len(self.topics) != n:
            raise ConfigError(f"{W}.topics: need one topic per camera ({n}), got {self.topics}")

    def cameras(self, base_dir: str | None = None, T_BI: Transform | None = None) -> tuple[CameraCalibration, ...]:
        """The rig as stated (what flight software may read): from ``calibration`` (a relative path taken from
        ``base_dir``; Kalibr's IMU frame is mounted at ``T_BI``, default the body frame) or from ``intrinsics`` and
        ``extrinsics`` / ``baseline``. Each camera's ``T_BC`` and ``intrinsics`` are what a VIO reads."""
        if self.calibration:
            from pathlib import Path

            from .kalibr import load_kalibr

            path = Path(self.calibration)
            if not path.is_absolute() and base_dir is not None:
                path = Path(base_dir) / path
            try:
                return load_kalibr(path, T_BI)
            except (OSError, ValueError) as e:
                raise ConfigError(f"StereoCameraParams.calibration: {e}") from None
        mounts = self.extrinsics or (
            Transform((0.1, self.baseline / 2, 0.0)),
            Transform((0.1, -self.baseline / 2, 0.0)),
        )
        return tuple(CameraCalibration(self.intrinsics, T, 0.0, f"cam{i}") for i, T in enumerate(mounts))

    def camera_topics(self, n: int) -> tuple[str, ...]:
        """The topics of a rig of ``n`` cameras."""
        if self.topics:
            if len(self.topics) != n:
                raise ConfigError(f"StereoCameraParams.topics: need {n} topics (one per camera), got {self.topics}")
            return self.topics
        return tuple(f"/sensors/cam{i}/image" for i in range(n))


def _stereo_camera(p: StereoCameraParams, ctx: BuildContext) -> list[Any]:
    world = ctx.require_world()
    rig = p.cameras(ctx.base_dir)
    topics = p.camera_topics(len(rig))
    cams = []
    for i, cal in enumerate(rig):
        T_BC = ctx.realism.simulated_extrinsic(f"{ctx.where}.cam{i}", cal.T_BC)  # where it truly is
        try:
            cams.append(
                RgbCamera(
                    cal.intrinsics,
                    T_BC,
                    light_W=p.light_W,
                    ambient=p.ambient,
                    nthreads=p.nthreads,
                    shadows=p.shadows,
                    grayscale=p.color == "gray",
                    exposure_s=p.exposure_s,
                    blur_samples=p.blur_samples,
                    line_time_s=p.line_time_s if p.shutter == "rolling" else 0.0,
                    full_well_e=p.full_well_e,
                    read_noise_dn=p.read_noise_dn,
                    seed=ctx.seed_for(f"{ctx.where}.cam{i}"),
                )
            )
        except ValueError as e:
            raise ConfigError(f"{ctx.where}.cam{i}: {e}") from None
    phase = 0.0
    if p.hw_sync:
        name, imu = ctx.sensor_of_type("imu", where=f"{ctx.where}.hw_sync")
        ratio = imu.params.rate_hz / p.rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ConfigError(
                f"{ctx.where}.hw_sync: the IMU's rate ({imu.params.rate_hz} Hz, sensors.{name}) must be a whole "
                f"multiple of rate_hz ({p.rate_hz} Hz) to trigger frames on its samples"
            )
        if ctx.part.phase_s:
            raise ConfigError(f"{ctx.where}: give phase_s or hw_sync, not both (hw_sync takes the IMU's phase)")
        phase = imu.phase_s
    return [CameraRigComponent(cams, world, topics, p.rate_hz, phase_s=phase, timeshift_s=rig[0].timeshift_s)]


register(SensorType("stereo_camera", CameraImage, None, "a rig of image cameras (stereo pair), one topic per camera"))
register(
    Kind(
        "sensor",
        "stereo_camera",
        StereoCameraParams,
        _stereo_camera,
        None,
        "stereo (or multi-camera) rig: /sensors/cam<i>/image, same stamps; calibration in its params",
        sensor_type="stereo_camera",
    )
)

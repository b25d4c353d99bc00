"""Sensor models (paper §2.2).

Inertial and navigation sensors share one error model: white noise, bias random walk and a turn-on
bias (:mod:`cufund.sensors.noise`), each sensor with its own seeded stream.

Ray-traced sensors — LiDARs (2-D, spinning 3-D, Livox) and pinhole depth / RGB cameras — work
standalone: give them a ``cufund.World`` (or a ``cufund.sensors.RaycastScene``) and a body pose (or
``pose_fn(t) -> (p_W, q_WB)``) and they return numpy records.
"""

from cufund._core.lidar import INVALID_ID, RaycastScene
from cufund.geometry import Transform

from . import patterns
from .allan import AllanFit, allan_deviation, fit_allan
from .barometer import BAROMETER_PRESETS, BarometerModel, BarometerParams, BarometerSensor, isa_altitude, isa_pressure
from .camera import CameraImage, CameraIntrinsics, DepthCamera, RgbCamera, d435_depth, d435_rgb, save_png
from .camera_component import CameraComponent, CameraRigComponent
from .camera_models import CameraCalibration
from .geodesy import GeoPoint, enu_to_lla, lla_to_enu
from .gps import GPS_PRESETS, GpsModel, GpsParams, GpsSensor
from .imu import IMU_PRESETS, ImuModel, ImuParams, ImuSensor, imu_preset
from .kalibr import dump_kalibr, load_kalibr
from .lidar import Lidar, LidarParams, PointCloud, mid360_params
from .lidar_component import LidarComponent
from .magnetometer import EarthField, MagnetometerModel, MagnetometerParams, MagnetometerSensor
from .noise import ErrorProcess, NoiseSpec
from .patterns import (
    CsvPattern,
    Mid360Pattern,
    PlanarPattern,
    RosettePattern,
    ScanPattern,
    ScanRays,
    SpinningPattern,
    avia,
    mid360,
    os1_64,
    vlp16,
)
from .power_monitor import PowerMonitor, PowerMonitorParams, PowerSystem

__all__ = [
    "INVALID_ID",
    "RaycastScene",
    "avia",
    "mid360",
    "os1_64",
    "vlp16",
    "AllanFit",
    "BAROMETER_PRESETS",
    "BarometerModel",
    "BarometerParams",
    "BarometerSensor",
    "CameraComponent",
    "CameraImage",
    "CameraCalibration",
    "CameraIntrinsics",
    "CameraRigComponent",
    "CsvPattern",
    "DepthCamera",
    "EarthField",
    "ErrorProcess",
    "GPS_PRESETS",
    "GeoPoint",
    "GpsModel",
    "GpsParams",
    "GpsSensor",
    "IMU_PRESETS",
    "ImuModel",
    "ImuParams",
    "ImuSensor",
    "Lidar",
    "LidarComponent",
    "LidarParams",
    "MagnetometerModel",
    "MagnetometerParams",
    "MagnetometerSensor",
    "Mid360Pattern",
    "NoiseSpec",
    "PlanarPattern",
    "PointCloud",
    "PowerMonitor",
    "PowerMonitorParams",
    "PowerSystem",
    "RgbCamera",
    "RosettePattern",
    "ScanPattern",
    "ScanRays",
    "SpinningPattern",
    "Transform",
    "allan_deviation",
    "d435_depth",
    "d435_rgb",
    "dump_kalibr",
    "enu_to_lla",
    "fit_allan",
    "imu_preset",
    "isa_altitude",
    "isa_pressure",
    "lla_to_enu",
    "load_kalibr",
    "mid360_params",
    "patterns",
    "save_png",
]

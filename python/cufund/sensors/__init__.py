"""Sensor models (paper §2.2). Inertial and navigation sensors share one error model: white noise, bias
random walk and a turn-on bias (:mod:`cufund.sensors.noise`), each sensor with its own seeded stream."""

from .allan import AllanFit, allan_deviation, fit_allan
from .barometer import BAROMETER_PRESETS, BarometerModel, BarometerParams, isa_altitude, isa_pressure
from .geodesy import GeoPoint, enu_to_lla, lla_to_enu
from .gps import GPS_PRESETS, GpsFix, GpsModel, GpsParams
from .imu import IMU_PRESETS, ImuModel, ImuParams, imu_preset
from .magnetometer import EarthField, MagnetometerModel, MagnetometerParams
from .noise import ErrorProcess, NoiseSpec

__all__ = [
    "AllanFit", "BAROMETER_PRESETS", "BarometerModel", "BarometerParams", "EarthField", "ErrorProcess",
    "GPS_PRESETS", "GeoPoint", "GpsFix", "GpsModel", "GpsParams", "IMU_PRESETS", "ImuModel", "ImuParams",
    "MagnetometerModel", "MagnetometerParams", "NoiseSpec", "allan_deviation", "enu_to_lla", "fit_allan",
    "imu_preset", "isa_altitude", "isa_pressure", "lla_to_enu",
]

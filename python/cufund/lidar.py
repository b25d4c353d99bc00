"""LiDAR ray casting: ``RaycastScene`` (Open3D-like, Embree 3) and the LiDAR sensor model."""

from ._core.lidar import INVALID_ID, RaycastScene
from .sensors.lidar import Lidar, LidarParams, PointCloud, mid360_params
from .sensors.patterns import (CsvPattern, Mid360Pattern, PlanarPattern, RosettePattern, ScanPattern, ScanRays,
                               SpinningPattern, avia, mid360, os1_64, vlp16)

__all__ = [
    "INVALID_ID", "CsvPattern", "Lidar", "LidarParams", "Mid360Pattern", "PlanarPattern", "PointCloud",
    "RaycastScene", "RosettePattern", "ScanPattern", "ScanRays", "SpinningPattern", "avia", "mid360",
    "mid360_params", "os1_64", "vlp16",
]

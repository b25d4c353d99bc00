"""Ray-traced sensors: LiDARs (2-D, spinning 3-D, Livox) and pinhole depth / RGB cameras.

Sensors work standalone: give them a ``cufund.World`` (or a ``cufund.lidar.RaycastScene``) and a
body pose (or ``pose_fn(t) -> (p_W, q_WB)``) and they return numpy records.
"""

from . import patterns
from .camera import CameraIntrinsics, DepthCamera, RgbCamera, d435_depth, d435_rgb, save_png
from .lidar import Lidar, LidarParams, PointCloud, mid360_params
from .patterns import (CsvPattern, Mid360Pattern, PlanarPattern, RosettePattern, ScanPattern, ScanRays,
                       SpinningPattern)
from .pose import Transform

__all__ = [
    "CameraIntrinsics", "CsvPattern", "DepthCamera", "Lidar", "LidarParams", "Mid360Pattern", "PlanarPattern",
    "PointCloud", "RgbCamera", "RosettePattern", "ScanPattern", "ScanRays", "SpinningPattern", "Transform",
    "d435_depth", "d435_rgb", "mid360_params", "patterns", "save_png",
]

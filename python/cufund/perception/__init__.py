"""Perception: tunnel frames from the LiDAR (paper §3.2, Fig. 9)."""

from typing import Any

from .detection import (
    FrameDetection,
    TunnelDetectorParams,
    detect_frames,
    detect_in_voxels,
    order_along_course,
    voxel_means,
)
from .tunnel_detector import TunnelDetector
from .voxel_accumulator import VoxelAccumulator

__all__ = [
    "FrameDetection",
    "TunnelDetector",
    "TunnelDetectorParams",
    "VoxelAccumulator",
    "detect_frames",
    "detect_in_voxels",
    "order_along_course",
    "plot_detection",
    "voxel_means",
]


def plot_detection(*args: Any, **kwargs: Any) -> Any:
    """Fig. 9-style plot of detections (see :func:`cufund.perception.plot.plot_detection`); imports matplotlib
    only when called."""
    from .plot import plot_detection as _plot

    return _plot(*args, **kwargs)

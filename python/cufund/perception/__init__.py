"""Perception: tunnel frames from the LiDAR (paper §3.2, Fig. 9); image detectors run with onnxruntime and the
labelled datasets they are trained on (docs/guides/detection.md)."""

from typing import Any

from .dataset import DatasetParams, Randomisation, write_dataset
from .dataset_labels import Box3D, ObjectLabel, ViewLabeller, ViewLabels
from .detection import (
    FrameDetection,
    TunnelDetectorParams,
    detect_frames,
    detect_in_voxels,
    order_along_course,
    voxel_means,
)
from .onnx_detector import Detections, OnnxDetector, load_class_names
from .onnx_detector_component import OnnxDetectorComponent
from .tunnel_detector import TunnelDetector
from .voxel_accumulator import VoxelAccumulator

__all__ = [
    "Box3D",
    "DatasetParams",
    "Detections",
    "FrameDetection",
    "ObjectLabel",
    "OnnxDetector",
    "OnnxDetectorComponent",
    "Randomisation",
    "TunnelDetector",
    "TunnelDetectorParams",
    "ViewLabeller",
    "ViewLabels",
    "VoxelAccumulator",
    "load_class_names",
    "write_dataset",
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

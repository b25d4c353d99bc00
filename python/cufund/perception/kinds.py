"""The built-in perception kinds of scenarios (``perception: {kind: onnx_detector, ...}``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most
from cufund.core.registry import Kind, register
from cufund.geometry import Transform
from cufund.sensors.camera import CameraIntrinsics, d435_depth, d435_rgb

from .onnx_detector import OnnxDetector
from .onnx_detector_component import OnnxDetectorComponent

_KNOWN_INTRINSICS = {"d435_rgb": d435_rgb, "d435_depth": d435_depth}


@dataclass(frozen=True)
class OnnxDetectorParams:
    """An ONNX detection model run on a camera's images (:class:`cufund.perception.OnnxDetector`)."""

    model: str = ""
    """The .onnx file (relative to the scenario file). Required (checked when the part is built)."""
    names: str | None = None
    """A YAML file whose ``names`` are the class names (default: the model's ``names`` metadata)."""
    camera: str = ""
    """The image sensor's name (default: the only camera, or the one called ``camera``)."""
    depth_camera: str | None = None
    """A depth camera mounted as ``camera`` (the same stated T_BC, else a ConfigError): with it, the detections are
    also placed in the world (Detections3D)."""
    stereo_camera: str | None = None
    """Instead of ``camera`` and ``depth_camera``: a ``stereo_camera`` rig's name; boxes are found in its first
    camera's (left) images and placed in the world from their disparity in the second's (right), the pair
    rectified (the same pinhole, no distortion, parallel axes, as stated in the rig's params)."""
    max_disparity: int = 96
    """With ``stereo_camera``: largest disparity searched [px] (the nearest depth is fx B / max_disparity)."""
    conf: float = 0.25
    """Score threshold [-]."""
    iou: float = 0.7
    """NMS IoU threshold (per class) [-]."""
    max_det: int = 300
    """Most detections per image."""
    rate_hz: float = 10.0
    """How often the newest image is processed [Hz]."""
    nthreads: int = 0
    """onnxruntime's threads (0: its default)."""

    def __post_init__(self) -> None:
        if not isinstance(self.model, str):
            raise ConfigError(f"perception.model must name an .onnx file, got {self.model!r}")
        for name in ("conf", "iou"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise ConfigError(f"perception.{name} must be a number in [0, 1], got {v!r}")
        v = self.rate_hz
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ConfigError(f"perception.rate_hz must be a finite number > 0 [Hz], got {v!r}")
        check_at_most(self, "perception", rate_hz=1e3)
        for name, lo, hi in (("max_det", 1, 100_000), ("nthreads", 0, 256), ("max_disparity", 2, 4096)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ConfigError(f"perception.{name} must be an integer in [{lo}, {hi}], got {v!r}")


def _intrinsics(spec: Any, where: str) -> CameraIntrinsics:
    """A camera sensor's pinhole: its params' ``intrinsics`` if it has them, else its kind's (D435 streams)."""
    k = getattr(spec.params, "intrinsics", None)
    if isinstance(k, CameraIntrinsics):
        return k
    if spec.kind in _KNOWN_INTRINSICS:
        return _KNOWN_INTRINSICS[spec.kind]()
    raise ConfigError(f"{where}: the intrinsics of a {spec.kind!r} camera are not known to the detector")


def _path(value: str, ctx: BuildContext) -> str:
    p = Path(value)
    return str(p if p.is_absolute() or ctx.base_dir is None else Path(ctx.base_dir) / p)


def _detector(p: OnnxDetectorParams, ctx: BuildContext) -> OnnxDetector:
    try:
        return OnnxDetector(
            _path(p.model, ctx),
            names=None if p.names is None else _path(p.names, ctx),
            conf=p.conf,
            iou=p.iou,
            max_det=p.max_det,
            nthreads=p.nthreads,
        )
    except ValueError as e:
        raise ConfigError(f"perception: {e}") from None


def _onnx_detector(p: OnnxDetectorParams, ctx: BuildContext) -> list[Any]:
    if not p.model:
        raise ConfigError("perception.model must name an .onnx file (the model is required)")
    if p.stereo_camera is not None:  # the left image, placed from the pair's disparities
        from .stereo_depth_build import stereo_detector

        return stereo_detector(p, ctx, _detector(p, ctx))
    name, image = ctx.sensor_of_type("camera", p.camera, "perception.camera")
    if image.kind == "d435_depth":  # its images are depths [m], not colour: every frame would be refused mid-run
        raise ConfigError(f"perception.camera: {name!r} is a depth camera ({image.kind}); name the colour camera")
    detector = _detector(p, ctx)
    if p.depth_camera is None:
        return [OnnxDetectorComponent(detector, image_topic=image.topic, rate_hz=p.rate_hz)]
    depth_name, depth = ctx.sensor_of_type("camera", p.depth_camera, "perception.depth_camera")
    if depth.kind == "d435_rgb":  # grey levels would be read as metres
        raise ConfigError(f"perception.depth_camera: {depth_name!r} is a colour camera ({depth.kind}), not a depth one")
    T_image, T_depth = image.extrinsic or Transform(), depth.extrinsic or Transform()
    offset = T_image.inverse() @ T_depth
    if np.linalg.norm(offset.t) > 1e-6 or abs(offset.q[0]) < 1.0 - 1e-12:
        # the boxes' rays are the image camera's, turned into the world with one mounting
        raise ConfigError(
            f"perception.depth_camera must be mounted as perception.camera (the same T_BC: the same centre and "
            f"axes), got {T_depth} and {T_image}"
        )
    return [
        OnnxDetectorComponent(
            detector,
            image_topic=image.topic,
            depth_topic=depth.topic,
            image_intrinsics=_intrinsics(image, "perception.camera"),
            depth_intrinsics=_intrinsics(depth, "perception.depth_camera"),
            T_BC=depth.extrinsic,  # as stated: flight software reads the mounting it was told
            rate_hz=p.rate_hz,
        )
    ]


register(
    Kind(
        "perception",
        "onnx_detector",
        OnnxDetectorParams,
        _onnx_detector,
        None,
        "an ONNX detection model (YOLOv8/YOLO11, SSD-style) on a camera's images with onnxruntime: 2-D boxes, and "
        "with a depth camera the objects in the estimated world frame",
    )
)

__all__ = ["OnnxDetectorParams"]

from . import camera_tunnel_kind  # noqa: E402, F401  (registers the perception kind camera: the camera-only tunnel)

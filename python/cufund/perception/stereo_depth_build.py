"""``perception: {kind: onnx_detector, stereo_camera: NAME}``: the detector on a stereo rig's left images, its
boxes placed in the world from their disparity in the right images (:mod:`.stereo_depth`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError

from .onnx_detector import OnnxDetector
from .onnx_detector_component import OnnxDetectorComponent
from .stereo_depth import stereo_baseline

__all__ = ["ColourStereoRig", "colour_stereo_rig", "stereo_detector"]


@dataclass(frozen=True)
class ColourStereoRig:
    """A stereo rig's first two cameras as its params state them: the sensor's name, the cameras, their image
    topics and the baseline [m] of the rectified pair."""

    name: str
    cameras: tuple[Any, ...]
    topics: tuple[str, ...]
    baseline_m: float


def colour_stereo_rig(ctx: BuildContext, rig_name: str) -> ColourStereoRig:
    """The ``stereo_camera`` sensor ``rig_name`` (``perception.stereo_camera``) as a detector on its left images
    and matching in its right ones needs it: colour, two cameras, rectified (ConfigError naming the key
    otherwise). Flight software reads the calibration it was told, never the world's."""
    name, rig = ctx.sensor_of_type("stereo_camera", rig_name, "perception.stereo_camera")
    params = rig.params
    if getattr(params, "color", "rgb") != "rgb":
        raise ConfigError(
            f"perception.stereo_camera: the detector needs colour images; set sensors.{name}.color: rgb "
            f"(got {params.color})"
        )
    cams = params.cameras(ctx.base_dir)
    if len(cams) < 2:
        raise ConfigError(f"perception.stereo_camera: {name!r} has {len(cams)} camera(s); a pair is needed")
    topics = params.camera_topics(len(cams))
    try:
        baseline = stereo_baseline(cams[0].intrinsics, cams[1].intrinsics, cams[0].T_BC, cams[1].T_BC)
    except ValueError as e:
        raise ConfigError(f"perception.stereo_camera ({name}): {e}") from None
    return ColourStereoRig(name, tuple(cams), tuple(topics), float(baseline))


def stereo_detector(p: Any, ctx: BuildContext, detector: OnnxDetector) -> list[Any]:
    """The component of ``p`` (:class:`~cufund.perception.kinds.OnnxDetectorParams` with ``stereo_camera``) on
    the rig's first two cameras as stated in its params (flight software reads the calibration it was told); a
    ConfigError if ``camera`` or ``depth_camera`` is also given, the rig is grey, or the pair is not rectified."""
    if p.camera or p.depth_camera is not None:
        raise ConfigError("perception: give stereo_camera, or camera (and depth_camera), not both")
    rig = colour_stereo_rig(ctx, p.stereo_camera)
    cams, topics = rig.cameras, rig.topics
    return [
        OnnxDetectorComponent(
            detector,
            image_topic=topics[0],
            right_topic=topics[1],
            image_intrinsics=cams[0].intrinsics,
            T_BC=cams[0].T_BC,
            baseline_m=rig.baseline_m,
            max_disparity=p.max_disparity,
            rate_hz=p.rate_hz,
        )
    ]

"""The perception kind ``camera`` (``--set perception=camera``): the tunnel's frames from a forward stereo rig and
the shipped frames model, instead of the LiDAR detector the tunnel mission builds (issue 26, item 4a). The
scenario loses its LiDAR and gains the rig in :mod:`cufund.scenarios.camera_tunnel`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError
from cufund.core.registry import Kind, register

from .camera_tunnel import CameraTunnelParams
from .camera_tunnel_component import CameraTunnelDetector
from .onnx_detector import OnnxDetector
from .onnx_detector_component import OnnxDetectorComponent
from .stereo_depth_build import colour_stereo_rig

__all__ = ["CameraPerceptionParams", "SHIPPED_FRAMES_MODEL"]

SHIPPED_FRAMES_MODEL = Path(__file__).resolve().parent / "models" / "frames_gates.onnx"
"""The frames-and-gates model cufund ships (classes tunnel_frame, gate)."""


@dataclass(frozen=True)
class CameraPerceptionParams:
    """The camera-only tunnel detector: a 2-D detector on the rig's left images, each frame's box measured from
    the stereo pair (:mod:`.camera_tunnel`). Lengths [m]."""

    model: str = ""
    """The .onnx detection model (relative to the scenario file; default: the shipped frames_gates.onnx)."""
    stereo_camera: str = ""
    """The stereo_camera rig's name (default: the only one)."""
    class_name: str = "tunnel_frame"
    """The model's class of the frames."""
    also_classes: tuple[str, ...] = ("gate",)
    """The model's other classes whose boxes are measured as frames too: the shipped model labels most frames seen
    from inside the course ``gate`` (in a flown paper layout every box past the first frame was); each box must
    still be refined to a frame's bars, top and bottom, which nothing else in a tunnel course passes."""
    conf: float = 0.5
    """Smallest score of a frame's box [-]."""
    rate_hz: float = 5.0
    """How often the newest left image is run through the model [Hz]."""
    nthreads: int = 0
    """onnxruntime's threads (0: its default)."""
    associate_m: float = 0.35
    """A measurement farther than this horizontally from every tracked frame's centre starts a new frame [m]."""
    bar: float = 0.05
    """Thickness and depth of the frames' bars (the competition's rules) [m]."""
    max_range: float = 6.0
    """Frames farther than this are not measured [m]."""
    max_disparity: int = 96
    """Largest disparity searched [px] (nearest frame measured: fx B / max_disparity)."""
    refine: bool = True
    """Refine each of the detector's boxes to the frame's bars, top and bottom in the pair before measuring it
    (:mod:`.camera_tunnel_refine`); false: the boxes' edges are taken as the frame's."""
    partial_min_width: float = 0.9
    """With ``refine``: a frame whose bars and top are found but not its bottom bar (merged with a nearer frame's
    bar across it) is measured with the rules' square opening's bottom, confirmed at its corners, when its opening
    is at least this wide (openings 1 m wide or more are square) [m]; 0: never."""
    partial_max_range: float = 2.5
    """Such a frame farther than this is not measured [m]."""

    def __post_init__(self) -> None:
        for name in ("model", "stereo_camera", "class_name"):
            if not isinstance(getattr(self, name), str):
                raise ConfigError(f"perception.{name} must be a string, got {getattr(self, name)!r}")
        if isinstance(self.also_classes, list):  # from YAML
            object.__setattr__(self, "also_classes", tuple(self.also_classes))
        if not isinstance(self.also_classes, tuple) or not all(isinstance(c, str) for c in self.also_classes):
            raise ConfigError(f"perception.also_classes must be a list of class names, got {self.also_classes!r}")
        for name, lo, hi in (("conf", 0.0, 1.0), ("rate_hz", 1e-3, 100.0), ("associate_m", 1e-3, 10.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
                raise ConfigError(f"perception.{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
        v = self.nthreads
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 256:
            raise ConfigError(f"perception.nthreads must be an integer in [0, 256], got {v!r}")
        self.geometry()  # bar, max_range, max_disparity checked there

    def geometry(self) -> CameraTunnelParams:
        return CameraTunnelParams(
            bar=self.bar,
            max_range=self.max_range,
            max_disparity=self.max_disparity,
            refine=self.refine,
            partial_min_width=self.partial_min_width,
            partial_max_range=self.partial_max_range,
        )


def _camera(p: CameraPerceptionParams, ctx: BuildContext) -> list[Any]:
    rig = colour_stereo_rig(ctx, p.stereo_camera)  # colour, a pair, rectified: ConfigError naming the key
    cams, topics, baseline = rig.cameras, rig.topics, rig.baseline_m
    K = cams[0].intrinsics
    if p.refine and not math.isclose(K.fx, K.fy, rel_tol=1e-6):  # the refinement's bar widths and level corners
        raise ConfigError(
            f"perception.refine: the box refinement needs square pixels (fx = fy), and sensors.{rig.name}'s "
            f"cameras have fx {K.fx:g} px, fy {K.fy:g} px; give equal focal lengths or set perception.refine: false"
        )
    model = Path(p.model) if p.model else SHIPPED_FRAMES_MODEL
    if p.model and not model.is_absolute() and ctx.base_dir is not None:
        model = Path(ctx.base_dir) / model
    if not model.is_file():
        raise ConfigError(
            f"perception.model: {model} is not a file"
            + ("" if p.model else " (the shipped frames model is missing from this install; give perception.model)")
        )
    try:
        detector = OnnxDetector(str(model), conf=p.conf, nthreads=p.nthreads)
    except ValueError as e:
        raise ConfigError(f"perception: {e}") from None
    if p.class_name not in detector.names:
        raise ConfigError(f"perception.class_name: {p.class_name!r} is not a class of {model.name} ({detector.names})")
    for c in p.also_classes:
        if c not in detector.names:
            raise ConfigError(
                f"perception.also_classes: {c!r} is not a class of {model.name} ({detector.names}); "
                "perception.also_classes=[] measures the class_name boxes alone"
            )
    cfg = ctx.config
    mission = getattr(cfg, "mission", None)
    expected = getattr(mission.params, "frames", None) if mission is not None and mission.kind == "tunnel" else None
    return [
        OnnxDetectorComponent(detector, image_topic=topics[0], rate_hz=p.rate_hz),  # boxes only: Detections2D
        CameraTunnelDetector(
            cams[0].intrinsics,
            baseline,
            cams[0].T_BC,  # as stated: flight software reads the mounting it was told
            topics[0],
            topics[1],
            params=p.geometry(),
            class_name=(p.class_name, *(c for c in p.also_classes if c != p.class_name)),
            min_score=p.conf,
            associate_m=p.associate_m,
            expected=expected,
            origin_W=cfg.start_p_W,
        ),
    ]


register(
    Kind(
        "perception",
        "camera",
        CameraPerceptionParams,
        _camera,
        None,
        "the tunnel's frames from a forward stereo rig (no LiDAR): a detector's boxes on the left image, each "
        "frame's opening centre and normal from stereo depth, published as the LiDAR detector's TunnelEstimate",
    )
)

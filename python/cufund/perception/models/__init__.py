"""The detection models cufund trains and ships (``cufund train-detector`` on ``cufund dataset`` output; each
``<name>.onnx`` beside its training config ``<name>.yaml``: dataset commands, seeds, epochs, input size).

- ``people_cars_pads``: person, car, landing_pad (the forest, scattered objects);
- ``frames_gates``: tunnel_frame, gate (the tunnel, scattered objects).

Both take a 240 x 320 letterboxed RGB input (a 640 x 480 image halved) and give ultralytics' YOLOv8 export
layout; run them with :class:`cufund.perception.onnx_detector.OnnxDetector` (onnxruntime only).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["SHIPPED", "model_path"]

SHIPPED = ("people_cars_pads", "frames_gates")
"""Names of the shipped models."""


def model_path(name: str) -> Path:
    """The ONNX file of a shipped model; a ValueError naming the choices for another name or a missing file."""
    if name not in SHIPPED:
        raise ValueError(f"model must be one of {', '.join(SHIPPED)}, got {name!r}")
    p = Path(__file__).with_name(f"{name}.onnx")
    if not p.is_file():
        raise ValueError(f"shipped model {name!r} is missing from this install ({p})")
    return p

"""Any ONNX object-detection model run with onnxruntime on the CPU: letterboxing, decoding, NMS, class names.

The output layout is chosen from the model's outputs:

- ``yolo``: one output (1, 4 + nc, N) — ultralytics' YOLOv8 / YOLO11 export: per anchor a box (centre u, centre
  v, width, height) in input pixels and nc class scores in [0, 1]; (1, N, 4 + nc), anchors first, when the
  second dimension is the larger and the last more than 4 (N > 4 + nc, as every real YOLO's is);
- ``end2end``: one output (1, N, 6) — rows (u_min, v_min, u_max, v_max, score, class) in input pixels, already
  suppressed (YOLOv10 / YOLO26-style exports); only the score threshold applies;
- ``ssd``: two outputs, boxes (1, N, 4) as (u_min, v_min, u_max, v_max) and scores (1, N, nc) — in input pixels,
  or in [0, 1] of the input when the model's metadata says ``box_units: normalized``.

Class names come from the model's metadata (``names``, as ultralytics writes it: ``{0: 'person', ...}``) or from a
YAML file (``names:`` as a list or a mapping, e.g. an ultralytics ``data.yaml``). Only ``onnxruntime`` is needed;
the model is read as bytes (at most :data:`MAX_MODEL_BYTES`), so an ONNX file cannot make it open other files.
"""

from __future__ import annotations

import ast
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, load_yaml

from .letterbox import Letterbox
from .nms import nms

MAX_MODEL_BYTES = 512 * 1024 * 1024
"""Largest model file read [bytes]."""
MAX_METADATA_CHARS = 1 << 20
"""Longest metadata value parsed as a literal (``names``, ``imgsz``) [characters]: parsing costs ~100 times its
length in memory."""
MAX_NMS = 30000
"""Candidates above the score threshold kept (highest first) before NMS, as ultralytics."""
LAYOUTS = ("yolo", "end2end", "ssd")


@dataclass(frozen=True)
class Detections:
    """One image's detections, in the original image's pixels."""

    boxes_xyxy: np.ndarray
    """(k, 4) float32 (u_min, v_min, u_max, v_max) [px], pixel edges, clipped to the image."""
    scores: np.ndarray
    """(k,) float32 in [0, 1], descending."""
    class_ids: np.ndarray
    """(k,) int64."""
    latency_ms: float
    """Wall time of :meth:`OnnxDetector.detect` [ms]."""

    def __len__(self) -> int:
        return len(self.scores)


def load_class_names(path: str | Path) -> tuple[str, ...]:
    """Class names from a YAML file whose ``names`` is a list, or a mapping {index: name} with indices 0..n-1. Read
    as every cufund YAML file (:func:`cufund.core.config.load_yaml`: plain data, its size, depth and aliases
    bounded); a ValueError when it is not such a file."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"names file {str(p)!r} does not exist")
    try:
        doc = load_yaml(p)
    except ConfigError as e:
        raise ValueError(f"names file {str(p)!r} is not valid YAML: {e}") from None
    if not isinstance(doc, dict) or "names" not in doc:
        raise ValueError(f"names file {str(p)!r} must be a mapping with a 'names' key (a list or {{index: name}})")
    return _names_from(doc["names"], f"{p}: names")


def _names_from(value: Any, where: str) -> tuple[str, ...]:
    if isinstance(value, (list, tuple)):
        names = list(value)
    elif isinstance(value, dict):
        keys = sorted(value)
        if not all(isinstance(k, int) and not isinstance(k, bool) for k in keys) or keys != list(range(len(keys))):
            raise ValueError(f"{where} must have the indices 0..n-1 as keys, got {keys[:10]!r}")
        names = [value[k] for k in keys]
    else:
        raise ValueError(f"{where} must be a list of names or a mapping {{index: name}}, got {type(value).__name__}")
    if not names or not all(isinstance(n, str) and n for n in names):
        raise ValueError(f"{where} must be non-empty strings, got {names[:10]!r}")
    return tuple(names)


def _metadata_literal(text: str) -> Any:
    """The Python literal in a metadata value (ultralytics writes its dicts and lists as their repr), parsed by
    ``ast.literal_eval`` (no code runs); ValueError (the reason) when it is none or longer than
    :data:`MAX_METADATA_CHARS`."""
    if len(text) > MAX_METADATA_CHARS:
        raise ValueError(f"{len(text)} characters, more than {MAX_METADATA_CHARS}")
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        raise ValueError("not a Python literal") from None


def _dim(d: Any) -> int | None:
    return d if isinstance(d, int) and not isinstance(d, bool) and d > 0 else None


class OnnxDetector:
    """Runs the ONNX detection model in ``model`` (a file path) on RGB images.

    ``names``: class names (a sequence, or a YAML file), else the model's ``names`` metadata, else ``class_<i>``.
    ``conf``: score threshold; ``iou``: NMS threshold (per class); ``max_det``: most boxes kept per image;
    ``imgsz``: (height, width) of the input when the model's input size is dynamic (else the model's, or its
    ``imgsz`` metadata). ``nthreads``: onnxruntime's intra-op threads (0: its default).
    """

    def __init__(
        self,
        model: str | Path,
        names: str | Path | list[str] | tuple[str, ...] | None = None,
        conf: float = 0.25,
        iou: float = 0.7,
        max_det: int = 300,
        imgsz: tuple[int, int] | None = None,
        nthreads: int = 0,
    ) -> None:
        for name, v in (("conf", conf), ("iou", iou)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be a number in [0, 1], got {v!r}")
        if isinstance(max_det, bool) or not isinstance(max_det, int) or not 1 <= max_det <= 100_000:
            raise ValueError(f"max_det must be an integer in [1, 100000], got {max_det!r}")
        if isinstance(nthreads, bool) or not isinstance(nthreads, int) or not 0 <= nthreads <= 256:
            raise ValueError(f"nthreads must be an integer in [0, 256], got {nthreads!r}")
        self.conf, self.iou, self.max_det = float(conf), float(iou), int(max_det)
        self.model_path = Path(model)
        self._anchors_first = False
        self._session = self._open(self.model_path, nthreads)
        meta = self._session.get_modelmeta().custom_metadata_map
        self._input = self._check_input(imgsz, meta)
        self.layout, self.num_classes = self._check_outputs(meta.get("end2end"))
        self.box_units = meta.get("box_units", "pixels")
        if self.box_units not in ("pixels", "normalized"):
            raise ValueError(f"{self.model_path}: metadata box_units must be 'pixels' or 'normalized'")
        self.names = self._names(names, meta)

    # --- loading -------------------------------------------------------------------------------
    @staticmethod
    def _open(path: Path, nthreads: int) -> Any:
        try:
            import onnxruntime as ort
        except ImportError:
            raise ValueError("the onnx_detector needs onnxruntime: pip install 'cufund[detect]'") from None
        if not path.is_file():
            raise ValueError(f"model file {str(path)!r} does not exist")
        size = path.stat().st_size
        if size > MAX_MODEL_BYTES:
            raise ValueError(f"model file {str(path)!r} is {size} bytes, more than the {MAX_MODEL_BYTES} allowed")
        options = ort.SessionOptions()
        options.intra_op_num_threads = nthreads
        options.inter_op_num_threads = 1
        options.log_severity_level = 3
        try:  # from bytes: external-data references cannot reach other files
            return ort.InferenceSession(path.read_bytes(), options, providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own Fail/InvalidGraph/InvalidProtobuf/... types
            msg = str(e).splitlines()[0][:300] if str(e) else type(e).__name__
            raise ValueError(f"model file {str(path)!r} is not a loadable ONNX model: {msg}") from None

    def _check_input(self, imgsz: tuple[int, int] | None, meta: dict[str, str]) -> tuple[str, int, int]:
        inputs = self._session.get_inputs()
        if len(inputs) != 1:
            raise ValueError(
                f"{self.model_path}: a detection model takes one image input, this one takes {len(inputs)}"
            )
        i = inputs[0]
        if i.type != "tensor(float)" or len(i.shape) != 4 or i.shape[1] != 3 or _dim(i.shape[0]) not in (None, 1):
            raise ValueError(
                f"{self.model_path}: input {i.name!r} must be a float tensor (1, 3, H, W), got {i.type} {i.shape}"
            )
        h, w = _dim(i.shape[2]), _dim(i.shape[3])
        if h is None or w is None:
            if imgsz is None and "imgsz" in meta:
                try:
                    imgsz = tuple(_metadata_literal(meta["imgsz"]))
                except (ValueError, TypeError):
                    imgsz = None
            if imgsz is None:
                raise ValueError(f"{self.model_path}: its input size is dynamic ({i.shape}): give imgsz=(H, W)")
            try:
                h, w = (int(x) for x in imgsz)
            except (TypeError, ValueError):
                raise ValueError(f"imgsz must be (height, width) in px, got {imgsz!r}") from None
        if not (1 <= h <= 8192 and 1 <= w <= 8192):
            raise ValueError(f"{self.model_path}: input size must be within 8192 px, got {h} x {w}")
        return i.name, h, w

    def _check_outputs(self, end2end: str | None) -> tuple[str, int | None]:
        """The layout from the output shapes; (1, A, 6) is end-to-end unless the metadata says ``end2end: False``
        (ultralytics writes it) and A > 4 (then a YOLO output of A - 4 classes and 6 anchors)."""
        outs = self._session.get_outputs()
        shapes = [list(o.shape) for o in outs]
        expected = (
            "one output (1, 4+nc, N) (YOLOv8/YOLO11), one (1, N, 6) (end-to-end), or two: boxes (1, N, 4) and "
            "scores (1, N, nc) (SSD-style)"
        )
        if any(o.type != "tensor(float)" for o in outs):
            raise ValueError(f"{self.model_path}: outputs must be float tensors; expected {expected}, got {shapes}")
        if len(outs) == 1 and len(shapes[0]) == 3:
            c, n = _dim(shapes[0][1]), _dim(shapes[0][2])
            if n == 6 and not (end2end == "False" and c is not None and c > 4):
                return "end2end", None
            if c is not None and c > 4 and (n is None or n <= 4 or c <= n):
                return "yolo", c - 4
            if n is not None and n > 4 and c is not None and c > n:  # (1, N, 4 + nc): anchors first
                self._anchors_first = True
                return "yolo", n - 4
        if len(outs) == 2 and all(len(s) == 3 for s in shapes):
            b, s = (0, 1) if _dim(shapes[0][2]) == 4 else (1, 0)
            nc = _dim(shapes[s][2])
            if _dim(shapes[b][2]) == 4 and nc is not None:
                self._ssd_order = (b, s)
                return "ssd", nc
        raise ValueError(f"{self.model_path}: unexpected outputs {shapes}; expected {expected}")

    def _names(self, names: Any, meta: dict[str, str]) -> tuple[str, ...]:
        if isinstance(names, (str, Path)):
            out = load_class_names(names)
        elif names is not None:
            out = _names_from(names, "names")
        elif "names" in meta:
            try:
                parsed = _metadata_literal(meta["names"])
            except ValueError as e:
                raise ValueError(
                    f"{self.model_path}: metadata 'names' is not a list or {{index: name}} ({e})"
                ) from None
            out = _names_from(parsed, f"{self.model_path}: metadata names")
        else:
            out = tuple(f"class_{i}" for i in range(self.num_classes or 0))
        if self.num_classes is not None and len(out) != self.num_classes:
            raise ValueError(f"{self.model_path}: {len(out)} class names for a model of {self.num_classes} classes")
        return out

    # --- inference -----------------------------------------------------------------------------
    @property
    def input_hw(self) -> tuple[int, int]:
        """(height, width) of the model's input [px]."""
        return self._input[1], self._input[2]

    def preprocess(self, image: object) -> tuple[np.ndarray, Letterbox]:
        """(H, W, 3) uint8 RGB -> the model's (1, 3, h, w) float32 input in [0, 1] and its letterbox."""
        if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            got = f"{image.shape} {image.dtype}" if isinstance(image, np.ndarray) else type(image).__name__
            raise ValueError(f"image must be an (H, W, 3) uint8 RGB array, got {got}")
        if min(image.shape[:2]) < 1:
            raise ValueError(f"image must have at least one pixel, got {image.shape}")
        box = Letterbox.fit(image.shape[:2], self.input_hw)
        x = box.apply(image).transpose(2, 0, 1)[None].astype(np.float32) / np.float32(255.0)
        return np.ascontiguousarray(x), box

    def raw(self, x: np.ndarray) -> list[np.ndarray]:
        """The model's outputs for an input from :meth:`preprocess`."""
        return list(self._session.run(None, {self._input[0]: x}))

    def detect(self, image: object) -> Detections:
        """Detections in ``image`` ((H, W, 3) uint8 RGB), highest score first."""
        t0 = time.perf_counter()
        x, box = self.preprocess(image)
        boxes, scores, classes = self.decode(self.raw(x))
        boxes = box.boxes_to_source(boxes).astype(np.float32)
        return Detections(boxes, scores, classes, (time.perf_counter() - t0) * 1e3)

    def decode(self, outputs: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw outputs -> (boxes_xyxy in input pixels, scores, class_ids) after the threshold and NMS. Rows with a
        non-finite box or score (a broken model's) are dropped, and an end-to-end row whose class is not an index
        into the names."""
        if self.layout == "end2end":
            rows = np.asarray(outputs[0], dtype=np.float32).reshape(-1, 6)
            c = rows[:, 5]
            valid = (c >= 0) & (c == np.floor(c)) & (c < len(self.names) if self.names else True)
            rows = rows[np.isfinite(rows).all(1) & valid & (rows[:, 4] > self.conf)][: self.max_det]
            return rows[:, :4], rows[:, 4], rows[:, 5].astype(np.int64)
        if self.layout == "yolo":
            pred = np.asarray(outputs[0], dtype=np.float32)
            if self._anchors_first:
                pred = pred.transpose(0, 2, 1)
            if pred.ndim != 3 or pred.shape[0] != 1 or pred.shape[1] != 4 + (self.num_classes or 0):
                raise ValueError(
                    f"{self.model_path}: output of shape {pred.shape}, expected (1, {4 + (self.num_classes or 0)}, N)"
                )
            pred = pred[0].T
            cls = pred[:, 4:]
            xywh = pred[:, :4]
            boxes = np.concatenate([xywh[:, :2] - xywh[:, 2:] / 2, xywh[:, :2] + xywh[:, 2:] / 2], 1)
        else:
            b, s = self._ssd_order
            boxes = np.asarray(outputs[b], dtype=np.float32).reshape(-1, 4)
            cls = np.asarray(outputs[s], dtype=np.float32).reshape(len(boxes), -1)
            if self.box_units == "normalized":
                h, w = self.input_hw
                boxes = boxes * np.array([w, h, w, h], np.float32)
        scores = cls.max(1) if cls.shape[1] else np.zeros(len(cls), np.float32)
        classes = cls.argmax(1) if cls.shape[1] else np.zeros(len(cls), np.int64)
        keep = (scores > self.conf) & np.isfinite(boxes).all(1)  # a NaN score is never above it
        boxes, scores, classes = boxes[keep], scores[keep], classes[keep]
        if len(scores) > MAX_NMS:
            top = np.argsort(-scores, kind="stable")[:MAX_NMS]
            boxes, scores, classes = boxes[top], scores[top], classes[top]
        i = nms(boxes, scores, self.iou, classes, self.max_det)
        return boxes[i], scores[i], classes[i].astype(np.int64)

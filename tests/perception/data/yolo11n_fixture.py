"""The YOLO11n fixture of tests/perception/test_onnx_detector.py: ultralytics' predictions on a YOLO11n export,
kept in git small enough to run in CI without torch or ultralytics.

- ``yolo11n_stripped.onnx``: the ONNX graph ultralytics exports from its own ``yolo11.yaml`` (5 classes, 320 px,
  opset 17) with the convolutions' weights and biases removed (their names, shapes and types kept; the DFL's
  fixed ``arange(16)`` weight, the anchors and strides stay); :func:`refill` puts weights back with a numpy-seeded
  rule, the same on any machine (``weights_sha256`` in the references says so);
- ``yolo11n_ultralytics.npz``: the test images (:func:`images`) and, per image, what ultralytics' real predictor
  (``YOLO(model.onnx).predict``: its AutoBackend, LetterBox, torchvision NMS and box scaling) gave on the refilled
  model: its letterboxed input (as the uint8 it divides by 255) and its boxes, scores and classes.

Regenerate both (only when ultralytics changes its export or its post-processing, or the fixture's rule changes),
in a venv holding torch, torchvision and ultralytics beside cufund (docs/guides/detection.md says how)::

    python tests/perception/data/yolo11n_fixture.py

This module imports only numpy and onnx at the top; ultralytics only inside :func:`main`.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import onnx
from onnx import numpy_helper

HERE = Path(__file__).resolve().parent
GRAPH = HERE / "yolo11n_stripped.onnx"
REFERENCE = HERE / "yolo11n_ultralytics.npz"
NAMES = {0: "tunnel_frame", 1: "gate", 2: "landing_pad", 3: "person", 4: "car"}
IMGSZ = 320
CONF = 0.3
IOU = 0.7
SEED = 0
CLASS_HEAD_GAIN = 100.0
"""The class head's last convolutions' weights are scaled by this, their biases drawn in [-3.5, -2.5]: then about
100 of the 2100 anchors score above :data:`CONF` in each image and NMS keeps about a third of them (He-scaled
weights alone give no score above it)."""
PALETTE = np.array([[90, 90, 90], [200, 60, 60], [40, 60, 190], [30, 170, 60], [150, 200, 230]], np.uint8)
"""The colour of each world object of the views (ground, person, car, gate); the sky (-1) takes the last."""
BOX_HEAD_GAIN = 100.0
"""The box head's last convolutions' (``model.<i>.cv2.<level>.2``) weights are scaled by this: the DFL's 16 logits
per side then spread, the boxes' sides range over about 85-175 px and their overlaps over all values (He-scaled
weights alone give every box 120 × 120 px, overlaps of a few values only: NMS at 0.7 and at 0.75 then keep the
same boxes)."""
ODD_SIZES = ((375, 500), (480, 640), (300, 200), (97, 333))
"""Image sizes (height, width) whose scale to 320 px is not exact: OpenCV's fixed-point resize differs from
cufund's by up to one grey level there."""


def stripped_initializers(model: onnx.ModelProto) -> list[onnx.TensorProto]:
    """The initializers the fixture strips and :func:`refill` fills: every Conv's weight and bias but the DFL's
    (a fixed ``arange(16)`` that turns the box distributions into distances), in the graph's order."""
    by_name = {t.name: t for t in model.graph.initializer}
    out: list[onnx.TensorProto] = []
    seen: set[str] = set()
    for node in model.graph.node:
        if node.op_type != "Conv" or "/dfl/" in node.name:
            continue
        for name in node.input[1:]:
            if name in by_name and name not in seen:
                seen.add(name)
                out.append(by_name[name])
    return out


def strip(model: onnx.ModelProto) -> onnx.ModelProto:
    """A copy of ``model`` whose :func:`stripped_initializers` hold no data (names, dims and types kept)."""
    stripped = onnx.ModelProto()
    stripped.CopyFrom(model)
    for t in stripped_initializers(stripped):
        for field in ("raw_data", "float_data"):
            t.ClearField(field)
    return stripped


def refill(stripped: onnx.ModelProto, seed: int = SEED) -> onnx.ModelProto:
    """A copy of the stripped graph with weights drawn from ``numpy.random.default_rng(seed)``: each Conv weight
    (O, I, kh, kw) uniform in ±sqrt(6 / (I kh kw)) (He's variance 2 / fan-in), biases zero; the class head's last
    convolutions (O = the number of classes) scaled by :data:`CLASS_HEAD_GAIN`, their biases in [-3.5, -2.5]; the
    box head's last ones scaled by :data:`BOX_HEAD_GAIN`. Only ``Generator.random`` (53-bit uniform doubles from
    PCG64) is drawn; the references' ``weights_sha256`` tells if a numpy ever draws other values."""
    model = onnx.ModelProto()
    model.CopyFrom(stripped)
    rng = np.random.default_rng(seed)
    nc = len(NAMES)
    for t in stripped_initializers(model):
        if t.data_type != onnx.TensorProto.FLOAT:
            raise ValueError(f"initializer {t.name!r}: float32 expected, got ONNX type {t.data_type}")
        dims = tuple(int(d) for d in t.dims)
        u = rng.random(int(np.prod(dims))).reshape(dims) * 2.0 - 1.0  # uniform in [-1, 1)
        if len(dims) == 4:
            w = u * np.sqrt(6.0 / (dims[1] * dims[2] * dims[3]))
            if dims[0] == nc:
                w *= CLASS_HEAD_GAIN
            elif re.fullmatch(r"model\.\d+\.cv2\.\d\.2\.weight", t.name):
                w *= BOX_HEAD_GAIN
        elif len(dims) == 1:
            w = -3.0 + 0.5 * u if dims[0] == nc else np.zeros(dims)
        else:
            raise ValueError(f"initializer {t.name!r}: a Conv weight (4-D) or bias (1-D) expected, got {dims}")
        t.ClearField("raw_data")
        t.ClearField("float_data")
        t.raw_data = w.astype("<f4").tobytes()
    return model


def weights_sha256(model: onnx.ModelProto) -> str:
    """SHA-256 of the refilled weights (in :func:`stripped_initializers`' order)."""
    h = hashlib.sha256()
    for t in stripped_initializers(model):
        h.update(numpy_helper.to_array(t).astype("<f4").tobytes())
    return h.hexdigest()


def load_refilled(path: Path) -> Path:
    """The fixture's model, refilled, written to ``path``."""
    path.write_bytes(refill(onnx.load(str(GRAPH))).SerializeToString())
    return path


def images(reference: dict[str, np.ndarray]) -> list[np.ndarray]:
    """The comparison's RGB images from the stored instance-id views (``views``: three 240 × 320 views of a
    person, a car and a gate, from cufund's ray caster when the fixture was made): each view painted by instance,
    at 320 × 240 and doubled pixel for pixel to 640 × 480 (halving is exact in any bilinear resize, so both
    pipelines get the same input), then seeded noise at 640 × 480 (4 × 4 blocks)."""
    out = []
    for ids in reference["views"]:
        img = PALETTE[ids.astype(np.int64)]
        out += [img, img.repeat(2, 0).repeat(2, 1)]
    rng = np.random.default_rng(1)
    out.append((rng.random((120, 160, 3)) * 255).astype(np.uint8).repeat(4, 0).repeat(4, 1))
    return out


def odd_images(reference: dict[str, np.ndarray]) -> list[np.ndarray]:
    """The first view painted and resampled (nearest) to each of :data:`ODD_SIZES`: flat regions and sharp edges
    (the stored inputs stay small), at scales a bilinear resize rounds."""
    img = PALETTE[reference["views"][0].astype(np.int64)]
    out = []
    for h, w in ODD_SIZES:
        rows = (np.arange(h) * img.shape[0]) // h
        cols = (np.arange(w) * img.shape[1]) // w
        out.append(np.ascontiguousarray(img[rows][:, cols]))
    return out


def image_sha256(images_: list[np.ndarray]) -> str:
    h = hashlib.sha256()
    for img in images_:
        h.update(repr(img.shape).encode())
        h.update(np.ascontiguousarray(img).tobytes())
    return h.hexdigest()


def render_views() -> np.ndarray:
    """Three 240 × 320 instance-id views (int8, -1 the sky) of a person, a car and a gate on a plane."""
    from cufund.geometry import yaw_quaternion
    from cufund.perception.dataset_labels import ViewLabeller
    from cufund.sensors.camera import CameraIntrinsics
    from cufund.worlds import labelled_objects as lo
    from cufund.worlds.world import World

    w = World()
    w.add_plane((40, 40), (0, 0, 0))
    lo.add_person(w, (5, 0, 0), 0.3, arm_swing=(0.5, -0.3))
    lo.add_car(w, (8, 2, 0), 1.0)
    lo.add_gate(w, (10, -2, 0), 0.2)
    labeller = ViewLabeller(w, CameraIntrinsics.from_fov(320, 240, 1.2), lo.CLASSES)
    views = [labeller.label((0.0, 0.5 * k, 1.2), yaw_quaternion(-0.1 * k)).instance_ids for k in range(3)]
    return np.stack(views).astype(np.int8)


def export_yolo11n(folder: Path) -> Path:
    """ultralytics' YOLO11n (5 classes) from its own YAML, exported to ONNX at 320 px, opset 17 (its weights are
    replaced by :func:`refill`)."""
    import torch
    import ultralytics
    import yaml
    from ultralytics import YOLO

    cfg = yaml.safe_load((Path(ultralytics.__file__).parent / "cfg/models/11/yolo11.yaml").read_text())
    cfg["nc"] = len(NAMES)
    (folder / "yolo11n.yaml").write_text(yaml.safe_dump(cfg))  # 'n' in the name: the nano scale
    torch.manual_seed(0)
    model = YOLO(str(folder / "yolo11n.yaml"), task="detect")
    model.model.names = dict(NAMES)
    path = model.export(format="onnx", imgsz=IMGSZ, opset=17, simplify=False, dynamic=False, verbose=False)
    return Path(path)


def ultralytics_predict(model_path: Path, images_rgb: list[np.ndarray]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """ultralytics' real predictor on each image (BGR, as it takes arrays): its rows (x1, y1, x2, y2, score,
    class) and its letterboxed input as uint8 (1, 3, H, W)."""
    import torch
    from ultralytics import YOLO

    yolo = YOLO(str(model_path), task="detect")
    rows, inputs = [], []
    for img in images_rgb:
        bgr = np.ascontiguousarray(img[..., ::-1])
        (result,) = yolo.predict(bgr, imgsz=IMGSZ, conf=CONF, iou=IOU, max_det=300, device="cpu", verbose=False)
        rows.append(result.boxes.data.cpu().numpy().astype(np.float32))
        x = yolo.predictor.preprocess([bgr])
        assert isinstance(x, torch.Tensor) and x.dtype == torch.float32, (type(x), x.dtype)
        u8 = np.rint(x.cpu().numpy() * 255.0)
        assert np.array_equal(u8.astype(np.float32) / np.float32(255.0), x.cpu().numpy())  # exactly uint8 / 255
        inputs.append(u8.astype(np.uint8))
    return rows, inputs


def main() -> None:
    import os
    import tempfile
    import warnings

    import onnxruntime
    import torch
    import torchvision
    import ultralytics

    torchvision.ops.nms(torch.zeros((1, 4)), torch.zeros(1), 0.5)  # its compiled ops load: the predictor uses them
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        folder = Path(tmp)
        os.environ["YOLO_OFFLINE"] = "1"
        os.environ["YOLO_CONFIG_DIR"] = str(folder / "settings")
        cwd = Path.cwd()
        os.chdir(folder)
        try:
            exported = onnx.load(str(export_yolo11n(folder)))
            GRAPH.write_bytes(strip(exported).SerializeToString())
            model_path = load_refilled(folder / "yolo11n_refilled.onnx")
            ref: dict[str, np.ndarray] = {"views": render_views()}
            imgs, odd = images(ref), odd_images(ref)
            rows, inputs = ultralytics_predict(model_path, imgs)
            odd_rows, odd_inputs = ultralytics_predict(model_path, odd)
        finally:
            os.chdir(cwd)
    for i, (r, x) in enumerate(zip(rows, inputs, strict=True)):
        ref[f"rows_{i}"], ref[f"input_{i}"] = r, x
    for i, (r, x) in enumerate(zip(odd_rows, odd_inputs, strict=True)):
        ref[f"odd_rows_{i}"], ref[f"odd_input_{i}"] = r, x
    ref["weights_sha256"] = np.array(weights_sha256(refill(onnx.load(str(GRAPH)))))
    ref["images_sha256"] = np.array(image_sha256(imgs + odd))
    ref["made_with"] = np.array(
        f"ultralytics {ultralytics.__version__}, torch {torch.__version__}, torchvision {torchvision.__version__}, "
        f"onnxruntime {onnxruntime.__version__}, onnx {onnx.__version__}, numpy {np.__version__}"
    )
    np.savez_compressed(REFERENCE, **ref)
    session = onnxruntime.InferenceSession(
        refill(onnx.load(str(GRAPH))).SerializeToString(), providers=["CPUExecutionProvider"]
    )
    scores = [session.run(None, {"images": x.astype(np.float32) / 255})[0][0, 4:].max(0) for x in inputs + odd_inputs]
    margin = min(float(np.abs(s - CONF).min()) for s in scores)  # a score this close to CONF could flip elsewhere
    print(f"anchors above conf {[int((s > CONF).sum()) for s in scores]}; closest score to it: {margin:.2e} away")
    counts = [len(r) for r in rows]
    print(f"{GRAPH.name}: {GRAPH.stat().st_size} bytes; {REFERENCE.name}: {REFERENCE.stat().st_size} bytes")
    print(f"boxes per image {counts} (total {sum(counts)}); odd sizes {[len(r) for r in odd_rows]}")
    print(str(ref["made_with"]))


if __name__ == "__main__":
    main()

"""The ONNX detector (issue 26 item 2): a YOLO11n exported by ultralytics from its YAML with seeded random weights
gives the same input and boxes as ultralytics' predictor (live where ultralytics is installed, and always against
its predictions recorded in tests/perception/data); SSD-style and end-to-end layouts decode
to the boxes put in them; NMS against torchvision's (or a brute-force reference); bad models and images are
refused with a clear error; the component places boxes in the world from a depth image and the estimate."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

from cufund.core.bus import Bus, BusView  # noqa: E402
from cufund.core.messages import CameraImage, Detections2D, Detections3D, Odometry, Topics  # noqa: E402
from cufund.geometry import Transform, quat_to_matrix, yaw_quaternion  # noqa: E402
from cufund.perception.letterbox import Letterbox, resize_bilinear  # noqa: E402
from cufund.perception.nms import box_iou, nms  # noqa: E402
from cufund.perception.onnx_detector import OnnxDetector, load_class_names  # noqa: E402
from cufund.perception.onnx_detector_component import OnnxDetectorComponent, boxes_to_world  # noqa: E402
from cufund.sensors.camera import R_CO, CameraIntrinsics  # noqa: E402

NAMES = {0: "tunnel_frame", 1: "gate", 2: "landing_pad", 3: "person", 4: "car"}


# --- small hand-built models ------------------------------------------------------------------------
def _model(
    outputs: dict[str, np.ndarray], path: Path, size: int | str = 64, meta: dict[str, str] | None = None
) -> Path:
    """A model of input 'images' (1, 3, size, size) (a str: dynamic) whose outputs are the given constants (each
    plus 0 × the input's mean, so the input is used)."""
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], keepdims=0),
        helper.make_node("Mul", ["m", "zero"], ["z"]),
    ]
    inits = [numpy_helper.from_array(np.zeros((), np.float32), "zero")]
    outs = []
    for name, value in outputs.items():
        inits.append(numpy_helper.from_array(value.astype(np.float32), f"{name}_c"))
        nodes.append(helper.make_node("Add", [f"{name}_c", "z"], [name]))
        outs.append(helper.make_tensor_value_info(name, TensorProto.FLOAT, list(value.shape)))
    graph = helper.make_graph(
        nodes, "g", [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, size, size])], outs, inits
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    for k, v in (meta or {}).items():
        model.metadata_props.add(key=k, value=v)
    onnx.checker.check_model(model)
    path.write_bytes(model.SerializeToString())
    return path


def test_ssd_layout_boxes_come_back_in_the_original_image(tmp_path):
    """Two SSD outputs (boxes in input pixels, scores per class): a 128 × 64 image in a 64 × 64 input is scaled by
    1/2 and padded 16 rows on top, so an input box (10, 20, 30, 40) is (20, 8, 60, 48) in the image."""
    boxes = np.array([[[10, 20, 30, 40], [11, 21, 31, 41], [0, 16, 64, 48]]], np.float32)
    scores = np.array([[[0.1, 0.9], [0.2, 0.8], [0.6, 0.3]]], np.float32)  # box 1 overlaps box 0: suppressed
    det = OnnxDetector(_model({"boxes": boxes, "scores": scores}, tmp_path / "ssd.onnx"), names=["a", "b"])
    assert det.layout == "ssd" and det.names == ("a", "b")
    out = det.detect(np.zeros((64, 128, 3), np.uint8))
    np.testing.assert_allclose(out.boxes_xyxy, [[20, 8, 60, 48], [0, 0, 128, 64]], atol=1e-4)
    np.testing.assert_allclose(out.scores, [0.9, 0.6], atol=1e-6)
    assert out.class_ids.tolist() == [1, 0]
    assert out.latency_ms > 0
    # normalised boxes (metadata box_units) scale by the input size first
    norm = _model({"boxes": boxes / 64, "scores": scores}, tmp_path / "n.onnx", meta={"box_units": "normalized"})
    out2 = OnnxDetector(norm, names=["a", "b"]).detect(np.zeros((64, 128, 3), np.uint8))
    np.testing.assert_allclose(out2.boxes_xyxy, out.boxes_xyxy, atol=1e-4)


def test_end2end_layout_only_thresholds(tmp_path):
    rows = np.array([[[1, 2, 11, 12, 0.9, 3], [1, 2, 11, 12, 0.8, 3], [5, 5, 6, 6, 0.1, 0]]], np.float32)
    path = _model({"output0": rows}, tmp_path / "e2e.onnx", meta={"names": repr(NAMES)})
    det = OnnxDetector(path, conf=0.25)
    assert det.layout == "end2end" and det.names == tuple(NAMES.values())
    out = det.detect(np.zeros((64, 64, 3), np.uint8))  # input size: no scaling, no padding
    np.testing.assert_allclose(out.boxes_xyxy, rows[0, :2, :4])  # no NMS: the model did it
    assert out.class_ids.tolist() == [3, 3]


def test_yolo_layout_decodes_centre_size_boxes(tmp_path):
    """(1, 4 + nc, N): columns (u_c, v_c, w, h, scores...)."""
    pred = np.zeros((1, 6, 3), np.float32)
    pred[0, :, 0] = [20, 30, 10, 20, 0.1, 0.7]  # box (15, 20, 25, 40), class 1
    pred[0, :, 1] = [21, 30, 10, 20, 0.6, 0.2]  # overlaps box 0 but another class: kept
    pred[0, :, 2] = [50, 50, 4, 4, 0.2, 0.1]  # below the threshold
    det = OnnxDetector(_model({"output0": pred}, tmp_path / "y.onnx"), conf=0.25)
    assert det.layout == "yolo" and det.names == ("class_0", "class_1")
    out = det.detect(np.zeros((64, 64, 3), np.uint8))
    np.testing.assert_allclose(out.boxes_xyxy, [[15, 20, 25, 40], [16, 20, 26, 40]])
    assert out.class_ids.tolist() == [1, 0]
    # the same anchors first, (1, N, 4 + nc), with more anchors than channels
    wide = np.zeros((1, 7, 12), np.float32)  # a third class, never scored; 12 anchors
    wide[:, :6, :3] = pred
    det_t = OnnxDetector(_model({"output0": wide.transpose(0, 2, 1).copy()}, tmp_path / "t.onnx"), conf=0.25)
    assert det_t.layout == "yolo" and det_t.num_classes == 3
    out_t = det_t.detect(np.zeros((64, 64, 3), np.uint8))
    np.testing.assert_allclose(out_t.boxes_xyxy, out.boxes_xyxy)


# --- bad input ---------------------------------------------------------------------------------------
def test_non_finite_outputs_are_dropped_not_published(tmp_path):
    """A broken model's NaN / infinite boxes or scores never reach the detections (a NaN box made the 3-D
    placement raise mid-run), nor an end-to-end row whose class is no index into the names."""
    boxes = np.array([[[np.nan, 20, 30, 40], [1, 2, np.inf, 5], [10, 20, 30, 40], [0, 0, 8, 8]]], np.float32)
    scores = np.array([[[0.1, 0.9], [0.9, 0.1], [0.8, 0.1], [np.nan, 0.7]]], np.float32)
    det = OnnxDetector(_model({"boxes": boxes, "scores": scores}, tmp_path / "ssd.onnx"), names=["a", "b"])
    out = det.detect(np.zeros((64, 64, 3), np.uint8))
    np.testing.assert_allclose(out.boxes_xyxy, [[10, 20, 30, 40]])
    rows = np.array(
        [
            [
                [1, 2, 11, 12, 0.9, 1],
                [np.nan, 2, 11, 12, 0.9, 0],
                [1, 2, 11, 12, np.nan, 0],
                [1, 2, 3, 4, 0.9, 5],
                [1, 2, 3, 4, 0.9, -1],
                [1, 2, 3, 4, 0.9, 0.5],
            ]
        ],
        np.float32,
    )
    e2e = OnnxDetector(_model({"output0": rows}, tmp_path / "e2e.onnx", meta={"names": repr(NAMES)}))
    out = e2e.detect(np.zeros((64, 64, 3), np.uint8))
    assert out.class_ids.tolist() == [1] and np.all(np.isfinite(out.boxes_xyxy))
    K = CameraIntrinsics(64, 64, 50.0, 50.0, 31.5, 31.5)
    centres, _, ok = boxes_to_world(
        det.detect(np.zeros((64, 64, 3), np.uint8)).boxes_xyxy,
        np.full((64, 64), 3.0, np.float32),
        K,
        K,
        Transform(),
        np.zeros(3),
        np.eye(3),
    )
    assert ok.tolist() == [True] and np.all(np.isfinite(centres))


def test_unexpected_outputs_are_refused_naming_them(tmp_path):
    path = _model({"logits": np.zeros((1, 10), np.float32)}, tmp_path / "cls.onnx")
    with pytest.raises(ValueError, match=r"unexpected outputs \[\[1, 10\]\]; expected one output \(1, 4\+nc, N\)"):
        OnnxDetector(path)
    three = {k: np.zeros((1, 5, 4), np.float32) for k in ("a", "b", "c")}
    with pytest.raises(ValueError, match="unexpected outputs"):
        OnnxDetector(_model(three, tmp_path / "three.onnx"))


def test_hostile_files_are_refused_without_crashing(tmp_path):
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(ValueError, match="is not a loadable ONNX model"):
        OnnxDetector(garbage)
    good = _model({"output0": np.zeros((1, 6, 3), np.float32)}, tmp_path / "good.onnx").read_bytes()
    cut = tmp_path / "cut.onnx"
    cut.write_bytes(good[: len(good) // 2])
    with pytest.raises(ValueError, match="is not a loadable ONNX model"):
        OnnxDetector(cut)
    # an initializer whose data is "external": a file beside the model, out of its folder and back (onnxruntime
    # refuses an absolute path itself, but opens this one for a model loaded from its path); read as bytes, the
    # model cannot make onnxruntime open it
    model = onnx.load_from_string(good)
    t = model.graph.initializer[1]
    t.ClearField("raw_data")
    t.data_location = TensorProto.EXTERNAL
    (tmp_path / "weights.bin").write_bytes(np.zeros((1, 6, 3), np.float32).tobytes())
    t.external_data.add(key="location", value=f"../{tmp_path.name}/weights.bin")
    ext = tmp_path / "ext.onnx"
    ext.write_bytes(model.SerializeToString())
    with pytest.raises(ValueError, match="is not a loadable ONNX model"):
        OnnxDetector(ext)
    with pytest.raises(ValueError, match="does not exist"):
        OnnxDetector(tmp_path / "nowhere.onnx")
    # metadata names that are code, not a literal
    evil = _model(
        {"output0": np.zeros((1, 6, 3), np.float32)}, tmp_path / "evil.onnx", meta={"names": "__import__('os')"}
    )
    with pytest.raises(ValueError, match="metadata 'names' is not a list"):
        OnnxDetector(evil)
    # metadata that costs ~100 times its length to parse is refused unparsed; a literal too deep to parse, in
    # the metadata imgsz of a dynamic input, is no MemoryError (the model then needs imgsz given)
    huge = _model(
        {"output0": np.zeros((1, 6, 3), np.float32)}, tmp_path / "huge.onnx", meta={"names": "[" + "1," * 600_000 + "]"}
    )
    with pytest.raises(ValueError, match="metadata 'names' is not a list .* more than 1048576"):
        OnnxDetector(huge)
    deep = _model(
        {"output0": np.zeros((1, 6, 3), np.float32)},
        tmp_path / "deep.onnx",
        size="s",
        meta={"imgsz": "-" * 100_000 + "1"},
    )
    with pytest.raises(ValueError, match="input size is dynamic"):
        OnnxDetector(deep)
    assert OnnxDetector(deep, imgsz=(64, 64)).input_hw == (64, 64)


def test_names_yaml_and_count_checks(tmp_path):
    path = _model({"output0": np.zeros((1, 6, 3), np.float32)}, tmp_path / "m.onnx")
    (tmp_path / "data.yaml").write_text("names: {0: frame, 1: gate}\n")
    assert OnnxDetector(path, names=tmp_path / "data.yaml").names == ("frame", "gate")
    assert load_class_names(tmp_path / "data.yaml") == ("frame", "gate")
    (tmp_path / "three.yaml").write_text("names: [a, b, c]\n")
    with pytest.raises(ValueError, match="3 class names for a model of 2 classes"):
        OnnxDetector(path, names=tmp_path / "three.yaml")
    (tmp_path / "gap.yaml").write_text("names: {0: a, 2: b}\n")
    with pytest.raises(ValueError, match="indices 0..n-1"):
        load_class_names(tmp_path / "gap.yaml")
    (tmp_path / "bad.yaml").write_text("names: [a\n")
    with pytest.raises(ValueError, match="not valid YAML"):
        load_class_names(tmp_path / "bad.yaml")
    # read as every cufund YAML file: bounded depth (PyYAML's own recursion let a RecursionError out)
    (tmp_path / "deep.yaml").write_text("names: " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ValueError, match="not valid YAML: .* nesting deeper than yaml_max_depth"):
        load_class_names(tmp_path / "deep.yaml")
    (tmp_path / "twice.yaml").write_text("names: [a]\nnames: [b]\n")
    with pytest.raises(ValueError, match="duplicate key 'names'"):
        load_class_names(tmp_path / "twice.yaml")
    with pytest.raises(ValueError, match="conf must be a number in"):
        OnnxDetector(path, conf=1.5)


def test_wrong_images_are_refused(tmp_path):
    det = OnnxDetector(_model({"output0": np.zeros((1, 6, 3), np.float32)}, tmp_path / "m.onnx"))
    for bad, what in (
        (np.zeros((64, 64, 3), np.float32), r"\(64, 64, 3\) float32"),
        (np.zeros((64, 64), np.uint8), r"\(64, 64\) uint8"),
        (np.zeros((64, 64, 4), np.uint8), r"\(64, 64, 4\) uint8"),
        ([[0, 0, 0]], "list"),
        (np.zeros((0, 5, 3), np.uint8), "at least one pixel"),
    ):
        with pytest.raises(ValueError, match=rf"image must be an \(H, W, 3\) uint8 RGB array, got {what}|{what}"):
            det.detect(bad)


def test_model_input_must_be_an_image(tmp_path):
    graph = helper.make_graph(
        [helper.make_node("Identity", ["x"], ["y"])],
        "g",
        [helper.make_tensor_value_info("x", TensorProto.INT64, [1, 3, 8, 8])],
        [helper.make_tensor_value_info("y", TensorProto.INT64, [1, 3, 8, 8])],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    (tmp_path / "int.onnx").write_bytes(model.SerializeToString())
    with pytest.raises(ValueError, match=r"must be a float tensor \(1, 3, H, W\), got tensor\(int64\)"):
        OnnxDetector(tmp_path / "int.onnx")


# --- NMS and letterbox against references --------------------------------------------------------------
def _reference_nms(boxes, scores, classes, iou):
    """Brute force, written from the definition: visit by descending score, keep a box unless a kept box of its
    class overlaps it by more than ``iou``."""
    keep = []
    for i in sorted(range(len(scores)), key=lambda k: -scores[k]):
        ok = True
        for j in keep:
            if classes[j] != classes[i]:
                continue
            a, b = boxes[i], boxes[j]
            iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
            ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
            inter = iw * ih
            union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
            if inter / union > iou:
                ok = False
                break
        if ok:
            keep.append(i)
    return keep


def test_nms_matches_the_definition_on_random_boxes():
    rng = np.random.default_rng(4)
    for _ in range(20):
        n = int(rng.integers(1, 60))
        xy = rng.uniform(0, 100, (n, 2))
        boxes = np.hstack([xy, xy + rng.uniform(5, 40, (n, 2))]).astype(np.float32)
        scores = rng.permutation(n).astype(np.float32) / n  # distinct
        classes = rng.integers(0, 3, n)
        iou = float(rng.uniform(0.2, 0.8))
        assert nms(boxes, scores, iou, classes).tolist() == _reference_nms(boxes, scores, classes, iou)
    assert box_iou(np.array([0, 0, 2, 2.0]), np.array([[1, 1, 3, 3.0]]))[0] == pytest.approx(1 / 7)


def test_letterbox_geometry():
    lb = Letterbox.fit((480, 640), (320, 320))  # 1/2: 240 x 320, 40 rows on each side
    assert (lb.scaled_hw, lb.top, lb.left) == ((240, 320), 40, 0)
    lb = Letterbox.fit((375, 500), (640, 640))  # 1.28: 480 x 640, 80 rows on each side
    assert (lb.scaled_hw, lb.top, lb.left) == ((480, 640), 80, 0)
    lb = Letterbox.fit((101, 50), (64, 64))  # odd padding: round(d / 2 - 0.1) before
    assert lb.scaled_hw == (64, 32) and lb.left == 16
    img = np.arange(4 * 4 * 3, dtype=np.uint8).reshape(4, 4, 3)
    np.testing.assert_array_equal(resize_bilinear(img.repeat(2, 0).repeat(2, 1), (4, 4)), img)


# --- ultralytics ---------------------------------------------------------------------------------------
# Live (torch and ultralytics installed): a YOLO11n built and exported here, against ultralytics' predictor.
# Recorded (always, CI included): the same network with numpy-seeded weights against what ultralytics' real
# predictor gave on it, stored by tests/perception/data/yolo11n_fixture.py (which says how to regenerate it).
DATA = Path(__file__).parent / "data"


def _fixture_module():
    """tests/perception/data/yolo11n_fixture.py (the stripped graph's refill rule, the images, the regeneration)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("yolo11n_fixture", DATA / "yolo11n_fixture.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def yolo11n(tmp_path_factory):
    """A YOLO11n (5 classes) built by ultralytics from its own YAML and exported to ONNX at 320 px, its weights
    then drawn by the recorded fixture's numpy-seeded rule (He-scaled convolutions, the class head scaled so that
    about 100 anchors pass the threshold; the DFL's fixed weights kept)."""
    pytest.importorskip("torch")
    pytest.importorskip("ultralytics")
    fx = _fixture_module()
    folder = tmp_path_factory.mktemp("yolo11n")
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mp.setenv("YOLO_OFFLINE", "1")
        mp.setenv("YOLO_CONFIG_DIR", str(folder / "settings"))
        mp.chdir(folder)
        exported = onnx.load(str(fx.export_yolo11n(folder)))
    path = folder / "yolo11n_refilled.onnx"
    path.write_bytes(fx.refill(fx.strip(exported)).SerializeToString())
    return path


def _ultralytics_reference(
    model_path: Path, image_rgb: np.ndarray, conf: float, iou: float, x: np.ndarray | None = None
):
    """ultralytics' predictor for an exported model, step by step: LetterBox(auto=False) on the BGR image, BGR ->
    RGB, / 255, the ONNX model, non_max_suppression, scale_boxes (its own NMS when torchvision is not imported;
    :func:`test_yolo11n_export_matches_ultralytics_predictor` runs the predictor itself)."""
    import onnxruntime as ort
    import torch
    from ultralytics.data.augment import LetterBox
    from ultralytics.utils.nms import non_max_suppression
    from ultralytics.utils.ops import scale_boxes

    if x is None:
        lb = LetterBox((320, 320), auto=False, stride=32)(image=np.ascontiguousarray(image_rgb[..., ::-1]))
        x = np.ascontiguousarray(lb[..., ::-1].transpose(2, 0, 1)[None]).astype(np.float32) / 255.0
    sess = ort.InferenceSession(str(model_path), providers=["CPUExecutionProvider"])
    out = sess.run(None, {sess.get_inputs()[0].name: x})[0]
    det = non_max_suppression(torch.from_numpy(out), conf, iou, max_det=300)[0]
    det[:, :4] = scale_boxes((320, 320), det[:, :4], image_rgb.shape[:2])
    return det.numpy(), x


def _images():
    """Views of labelled objects painted by instance (each object a colour), 320 × 240 and doubled pixel for pixel
    to 640 × 480 (halving those is exact in any bilinear resize, so both pipelines see the same input), and noise
    (the recorded fixture's images, rendered here)."""
    fx = _fixture_module()
    return fx.images({"views": fx.render_views()})


def _assert_same_detections(ours, rows: np.ndarray, score_atol: float = 1e-6) -> None:
    """cufund's detections against ultralytics' rows (x1, y1, x2, y2, score, class): the same count, boxes within
    the issue's 1 px, scores within ``score_atol``, the same classes in the same order."""
    assert len(ours) == len(rows)
    np.testing.assert_allclose(ours.boxes_xyxy, rows[:, :4], atol=1.0)
    np.testing.assert_allclose(ours.scores, rows[:, 4], atol=score_atol)
    assert ours.class_ids.tolist() == rows[:, 5].astype(int).tolist()


def test_yolo11n_export_matches_ultralytics_postprocessing(yolo11n):
    det = OnnxDetector(yolo11n, conf=0.3, iou=0.7)
    assert det.layout == "yolo" and det.num_classes == 5 and det.input_hw == (320, 320)
    assert det.names == tuple(NAMES.values())  # from the export's metadata
    total = 0
    for img in _images():
        ours = det.detect(img)
        ref, x = _ultralytics_reference(yolo11n, img, 0.3, 0.7)
        np.testing.assert_array_equal(det.preprocess(img)[0], x)  # same letterboxed input, bit for bit
        _assert_same_detections(ours, ref)
        total += len(ours)
    assert total > 20  # enough boxes passed the threshold for the comparison to mean something


def _torchvision_or_skip():
    torch = pytest.importorskip("torch")
    try:
        import torchvision

        torchvision.ops.nms(torch.zeros((1, 4)), torch.zeros(1), 0.5)
    except Exception as e:  # absent, or its compiled ops do not load with this torch (a RuntimeError)
        pytest.skip(f"torchvision's NMS is not usable here: {type(e).__name__}")
    return torch, torchvision


def test_yolo11n_export_matches_ultralytics_predictor(yolo11n, tmp_path, monkeypatch):
    """ultralytics' real predictor, ``YOLO(model.onnx).predict``: its AutoBackend on onnxruntime, LetterBox, NMS
    (torchvision's, with its class-offset trick) and box scaling; its own letterboxed input is ours bit for bit."""
    _torchvision_or_skip()
    monkeypatch.setenv("YOLO_OFFLINE", "1")
    monkeypatch.setenv("YOLO_CONFIG_DIR", str(tmp_path / "settings"))
    monkeypatch.chdir(tmp_path)
    det = OnnxDetector(yolo11n, conf=0.3, iou=0.7)
    imgs = _images()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fx = _fixture_module()
        rows, inputs = fx.ultralytics_predict(yolo11n, imgs)
    for img, r, x in zip(imgs, rows, inputs, strict=True):
        np.testing.assert_array_equal(det.preprocess(img)[0], x.astype(np.float32) / np.float32(255))
        _assert_same_detections(det.detect(img), r)
    assert sum(len(r) for r in rows) > 20


def test_letterbox_of_any_size_matches_ultralytics_to_one_grey_level(yolo11n):
    """Sizes whose scale is not exact: the input differs from OpenCV's fixed-point resize by at most one grey
    level, and on ultralytics' own input tensor our decoding, NMS and box scaling give its boxes."""
    det = OnnxDetector(yolo11n, conf=0.3, iou=0.7)
    rng = np.random.default_rng(2)
    for h, w in ((375, 500), (480, 640), (300, 200), (97, 333)):
        img = (rng.random((h, w, 3)) * 255).astype(np.uint8)
        ref, x = _ultralytics_reference(yolo11n, img, 0.3, 0.7)
        _assert_letterbox_within_one_grey_level(det, img, x)
        boxes, scores, classes = det.decode(det.raw(x))
        boxes = det.preprocess(img)[1].boxes_to_source(boxes)
        assert len(boxes) == len(ref)
        np.testing.assert_allclose(boxes, ref[:, :4], atol=1e-3)
        np.testing.assert_allclose(scores, ref[:, 4], atol=1e-6)


def _assert_letterbox_within_one_grey_level(det: OnnxDetector, img: np.ndarray, x: np.ndarray) -> None:
    """Our letterboxed input against ultralytics' ``x``: the same shape, the padding (grey 114) in the same
    places, the scaled image within one grey level."""
    ours_x, box = det.preprocess(img)
    assert ours_x.shape == x.shape == (1, 3, *det.input_hw)
    assert np.abs(ours_x - x).max() * 255 <= 1.0 + 1e-4
    inside = np.zeros(det.input_hw, bool)
    inside[box.top : box.top + box.scaled_hw[0], box.left : box.left + box.scaled_hw[1]] = True
    assert np.all(x[0][:, ~inside] == np.float32(114) / 255) and np.all(ours_x[0][:, ~inside] == x[0][:, ~inside])


# --- the recorded ultralytics predictions (no torch, no ultralytics) ----------------------------------------
RECORDED_SCORE_ATOL = 1e-5
"""Scores against the recorded ones: onnxruntime on another machine (other kernels, another summation order)
gives other float32 roundings, which the heads' gains amplify: its own graph optimisation levels put this model's
scores up to 1.8e-6 and its boxes up to 1e-3 px apart (the live comparisons, one session, agree to the bit)."""
RECORDED_ODD_BOX_ATOL = 1e-2
"""Boxes of the odd sizes against the recorded ones [px] (the same reason)."""


@pytest.fixture(params=["all", "basic"])
def ort_optimization(request, monkeypatch):
    """onnxruntime's graph optimisation at its default level ("all") or at "basic" (no layout transformation or
    convolution fusions: the outputs rounded as another machine's kernels may round them)."""
    if request.param == "basic":
        import onnxruntime as ort

        session = ort.InferenceSession

        def basic(model, options=None, *args, **kwargs):
            options = options if options is not None else ort.SessionOptions()
            options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_BASIC
            return session(model, options, *args, **kwargs)

        monkeypatch.setattr(ort, "InferenceSession", basic)
    return request.param


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """The fixture module, its references and the refilled model (checked to be the model they were made on)."""
    fx = _fixture_module()
    with np.load(fx.REFERENCE) as f:
        ref = {k: f[k] for k in f.files}
    path = fx.load_refilled(tmp_path_factory.mktemp("recorded") / "yolo11n.onnx")
    assert fx.weights_sha256(onnx.load(str(path))) == str(ref["weights_sha256"]), (
        "the refilled weights differ from those the references were recorded on (numpy's stream?): regenerate "
        "with tests/perception/data/yolo11n_fixture.py"
    )
    assert fx.image_sha256(fx.images(ref) + fx.odd_images(ref)) == str(ref["images_sha256"])
    return fx, ref, path


def test_yolo11n_matches_the_recorded_ultralytics_predictor(recorded, ort_optimization):
    """On the images the fixture stores: cufund's letterboxed input is ultralytics' bit for bit, and its
    detections are ultralytics' (1 px, :data:`RECORDED_SCORE_ATOL`, the same classes and count), with NMS
    suppressing over a third of the candidates (so a broken NMS shows)."""
    fx, ref, path = recorded
    det = OnnxDetector(path, conf=fx.CONF, iou=fx.IOU)
    assert det.layout == "yolo" and det.num_classes == 5 and det.input_hw == (fx.IMGSZ, fx.IMGSZ)
    assert det.names == tuple(NAMES.values())  # from the export's metadata
    total = candidates = 0
    for i, img in enumerate(fx.images(ref)):
        x, _ = det.preprocess(img)
        np.testing.assert_array_equal(x * 255, ref[f"input_{i}"].astype(np.float32), err_msg=f"image {i}")
        rows = ref[f"rows_{i}"]
        _assert_same_detections(det.detect(img), rows, RECORDED_SCORE_ATOL)
        total += len(rows)
        candidates += int((det.raw(x)[0][0, 4:].max(0) > fx.CONF).sum())
    assert total > 20 and candidates > 1.5 * total


def test_odd_sizes_match_the_recorded_ultralytics_predictor(recorded, ort_optimization):
    """Sizes whose scale is not exact: cufund's input within one grey level of ultralytics' (the padding the
    same), and on ultralytics' own input cufund's decoding, NMS and box scaling give its boxes."""
    fx, ref, path = recorded
    det = OnnxDetector(path, conf=fx.CONF, iou=fx.IOU)
    for i, img in enumerate(fx.odd_images(ref)):
        x = ref[f"odd_input_{i}"].astype(np.float32) / np.float32(255)
        _assert_letterbox_within_one_grey_level(det, img, x)
        boxes, scores, classes = det.decode(det.raw(x))
        boxes = det.preprocess(img)[1].boxes_to_source(boxes)
        rows = ref[f"odd_rows_{i}"]
        assert len(boxes) == len(rows) > 0, img.shape
        np.testing.assert_allclose(boxes, rows[:, :4], atol=RECORDED_ODD_BOX_ATOL)
        np.testing.assert_allclose(scores, rows[:, 4], atol=RECORDED_SCORE_ATOL)
        assert classes.tolist() == rows[:, 5].astype(int).tolist()


def test_nms_matches_torchvision_when_it_loads():
    torch, torchvision = _torchvision_or_skip()
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 100, (200, 2))
    boxes = np.hstack([xy, xy + rng.uniform(5, 40, (200, 2))]).astype(np.float32)
    scores = rng.permutation(200).astype(np.float32) / 200
    classes = rng.integers(0, 4, 200)
    ref = torchvision.ops.batched_nms(torch.from_numpy(boxes), torch.from_numpy(scores), torch.from_numpy(classes), 0.5)
    assert nms(boxes, scores, 0.5, classes, max_det=1000).tolist() == ref.tolist()


# --- the component ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("depth_K", [None, CameraIntrinsics(40, 30, 20.0, 20.0, 19.5, 14.5)])
def test_component_publishes_2d_and_world_3d_from_depth_and_the_estimate(tmp_path, depth_K):
    """A box around pixel centre (40, 24) of a 64 × 64 image with the depth 4 m there: its world position is the
    camera ray through that pixel at depth 4 m, moved by the estimate's pose at the image's capture time (yawed
    90°, between two estimates) and the mounting; the same with a depth camera of other intrinsics at the same
    centre."""
    rows = np.array([[[36.5, 20.5, 44.5, 28.5, 0.9, 3]]], np.float32)  # centre (40.5, 24.5) in edges
    det = OnnxDetector(_model({"output0": rows}, tmp_path / "e2e.onnx", meta={"names": repr(NAMES)}))
    K = CameraIntrinsics(64, 64, 50.0, 50.0, 31.5, 31.5)
    Kd = depth_K or K
    T_BC = Transform((0.1, 0.0, -0.05), tuple(yaw_quaternion(0.0)))
    comp = OnnxDetectorComponent(
        det, depth_topic=Topics.DEPTH_IMAGE, image_intrinsics=K, depth_intrinsics=Kd, T_BC=T_BC
    )
    bus = Bus()
    view = BusView(bus, comp.name, comp.inputs + comp.optional_inputs, comp.outputs, deny_truth=True)
    comp.reset()
    comp.setup(view)
    q = yaw_quaternion(np.pi / 2)
    for t, y in ((0.0, 1.8), (0.2, 2.2)):  # at the image's capture time 0.1: (1, 2, 1.5), interpolated
        bus.publish(Topics.ESTIMATE, Odometry(t, np.array([1.0, y, 1.5]), np.zeros(3), q, np.zeros(3)))
    bus.publish(Topics.RGB_IMAGE, CameraImage(0.1, np.zeros((64, 64, 3), np.uint8)))
    depth = np.full((Kd.height, Kd.width), 4.0, np.float32)
    depth[0, :] = np.nan  # a missing row away from the box changes nothing
    bus.publish(Topics.DEPTH_IMAGE, CameraImage(0.1, depth))
    sub2, sub3 = bus.subscribe(Topics.DETECTIONS_2D), bus.subscribe(Topics.DETECTIONS_3D)
    comp.step(0.2, view)
    (d2,), (d3,) = sub2.take(), sub3.take()
    assert isinstance(d2, Detections2D) and isinstance(d3, Detections3D)
    assert d2.t == d3.t == 0.1 and d2.class_names[3] == "person" and d2.latency_ms > 0
    np.testing.assert_allclose(d2.boxes_xyxy, rows[0, :, :4])
    p_O = np.array([(40.0 - 31.5) / 50 * 4, (24.0 - 31.5) / 50 * 4, 4.0])
    R_WB = quat_to_matrix(q)
    expected = np.array([1.0, 2.0, 1.5]) + R_WB @ (np.array(T_BC.t) + T_BC.R @ R_CO @ p_O)
    np.testing.assert_allclose(d3.centres_W[0], expected, atol=1e-9)
    np.testing.assert_allclose(d3.sizes_m[0], [8 / 50 * 4, 8 / 50 * 4])
    assert comp.latencies_ms and comp.frames == 1
    with pytest.raises(ValueError, match="not ground truth"):
        OnnxDetectorComponent(det, state_topic=Topics.TRUTH_ODOMETRY)


def test_a_box_beyond_a_narrower_depth_image_has_no_depth():
    """A depth camera of a narrower field of view at the same centre: a box near the colour image's corner falls
    outside the depth image and gets no position (the depth image's edge pixels are another direction's); a box
    it overlaps takes the depth of the part it sees."""
    K = CameraIntrinsics(64, 64, 50.0, 50.0, 31.5, 31.5)
    Kd = CameraIntrinsics(64, 64, 100.0, 100.0, 31.5, 31.5)  # half the field of view
    depth = np.full((64, 64), 3.0, np.float32)
    boxes = np.array([[0.0, 0.0, 6.0, 6.0], [28.0, 28.0, 36.0, 36.0], [10.0, 28.0, 20.0, 36.0]])
    centres, sizes, ok = boxes_to_world(boxes, depth, K, Kd, Transform(), np.zeros(3), np.eye(3))
    assert ok.tolist() == [False, True, True]
    assert np.all(np.isnan(centres[0])) and np.all(np.isnan(sizes[0]))
    np.testing.assert_allclose(centres[1:, 0], 3.0)  # the optical axis is the body's x (R_CO), depth 3 m


def test_component_waits_for_an_estimate_covering_the_image(tmp_path):
    rows = np.array([[[0, 0, 8, 8, 0.9, 0]]], np.float32)
    det = OnnxDetector(_model({"output0": rows}, tmp_path / "e2e.onnx"))
    K = CameraIntrinsics(64, 64, 50.0, 50.0, 31.5, 31.5)
    comp = OnnxDetectorComponent(det, depth_topic=Topics.DEPTH_IMAGE, image_intrinsics=K, depth_intrinsics=K)
    bus = Bus()
    view = BusView(bus, comp.name, comp.inputs + comp.optional_inputs, comp.outputs, deny_truth=True)
    comp.reset()
    comp.setup(view)
    sub3 = bus.subscribe(Topics.DETECTIONS_3D)
    bus.publish(Topics.ESTIMATE, Odometry(0.0, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)))
    bus.publish(Topics.RGB_IMAGE, CameraImage(0.5, np.zeros((64, 64, 3), np.uint8)))
    bus.publish(Topics.DEPTH_IMAGE, CameraImage(0.5, np.full((64, 64), 2.0, np.float32)))
    comp.step(0.5, view)
    assert sub3.take() == []  # the image is newer than every estimate: no pose for it yet
    # the estimator's output for 0.5 arrives later (its latency): the frame is placed then, with its own stamp
    bus.publish(Topics.ESTIMATE, Odometry(0.6, np.ones(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)))
    comp.step(0.6, view)
    (d3,) = sub3.take()
    assert d3.t == 0.5 and len(d3.centres_W) == 1
    x = ((0 - 0.5 - 31.5) / 50 + (8 - 0.5 - 31.5) / 50) / 2  # the box's centre direction, both axes
    p_W = np.full(3, 0.5 / 0.6)  # the pose interpolated at the capture time
    np.testing.assert_allclose(d3.centres_W[0], p_W + R_CO @ np.array([x * 2, x * 2, 2.0]), atol=1e-9)
    with pytest.raises(ValueError, match="image_intrinsics and depth_intrinsics are needed"):
        OnnxDetectorComponent(det, depth_topic=Topics.DEPTH_IMAGE)


def test_scenario_part_perception_onnx_detector(tmp_path):
    """``perception: {kind: onnx_detector}`` in a scenario: built from the camera sensors (D435 colour and depth,
    the model path relative to the scenario file), run on the estimate (never ground truth), 2-D and 3-D
    detections published; a bad model is a ConfigError naming the part."""
    from cufund.core.config import ConfigError
    from cufund.scenarios.build import build_simulation, run_built
    from cufund.scenarios.schema import load_scenario

    rows = np.array([[[300, 220, 340, 260, 0.9, 0]]], np.float32)
    _model({"output0": rows}, tmp_path / "m.onnx", size=640, meta={"names": repr(NAMES)})
    (tmp_path / "s.yaml").write_text(
        "name: detect\nworld: {kind: imav2025_tunnel}\nvehicle: cu_astro\n"
        "sensors:\n  imu: {kind: icm42688p}\n  pose: {kind: pose, rate_hz: 100.0}\n"
        "  camera: {kind: d435_rgb, rate_hz: 5}\n  depth: {kind: d435_depth, rate_hz: 5}\n"
        "estimator: {kind: imu_propagator}\n"
        "perception: {kind: onnx_detector, model: m.onnx, depth_camera: depth, rate_hz: 5}\n"
        "trajectory: {waypoints: [[-2, 0, 1], [-1.5, 0, 1]]}\nstart_p_W: [-2, 0, 0]\nduration: 1.0\n"
        "realism: ideal\n"
    )
    cfg = load_scenario(tmp_path / "s.yaml")
    built = build_simulation(cfg)
    (comp,) = [c for c in built.simulator.components if isinstance(c, OnnxDetectorComponent)]
    assert comp.state_topic == Topics.ESTIMATE and comp.image_intrinsics.fx == 615.0
    run_built(built)
    assert comp.frames >= 4 and all(ms > 0 for ms in comp.latencies_ms)
    d3 = built.simulator.bus.latest(Topics.DETECTIONS_3D)
    assert isinstance(d3, Detections3D) and len(d3.centres_W) == 1  # the tunnel's wall or frames behind the box
    assert np.all(np.isfinite(d3.centres_W)) and d3.class_names[0] == "tunnel_frame"
    (tmp_path / "bad.onnx").write_bytes(b"not a model")
    with pytest.raises(ConfigError, match="perception: model file .* is not a loadable ONNX model"):
        build_simulation(load_scenario(tmp_path / "s.yaml", ["perception.model=bad.onnx"]))
    # the two cameras swapped: depths fed to the detector (refused at every frame mid-run), grey levels read as
    # metres
    with pytest.raises(ConfigError, match="perception.camera: 'depth' is a depth camera"):
        build_simulation(load_scenario(tmp_path / "s.yaml", ["perception.camera=depth"]))
    with pytest.raises(ConfigError, match="perception.depth_camera: 'camera' is a colour camera"):
        build_simulation(load_scenario(tmp_path / "s.yaml", ["perception.depth_camera=camera"]))
    # a depth camera mounted elsewhere than the image camera: the boxes' rays would be turned with its mounting
    for key in ("sensors.depth.T_BC.p=[0.0,0.05,0.0]", "sensors.camera.T_BC.q=[0.9659258,0.0,0.0,0.258819]"):
        with pytest.raises(ConfigError, match="depth_camera must be mounted as perception.camera"):
            build_simulation(load_scenario(tmp_path / "s.yaml", [key]))

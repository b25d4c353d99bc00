"""`cufund train-detector` (cufund.perception.train_detector): the target assignment, the YOLOv8 export layout
(the ONNX model's output equals torch's own inference on 20 images), and a short training run end to end. Skipped
without torch (the detect-train extra); the configuration checks run without it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cufund.apps.cli import main
from cufund.core.config import ConfigError
from cufund.perception.train_detector import TrainDetectorConfig, load_yolo_dataset


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    """23 frames (20 for training) of the forest with scattered objects, 160 x 120 (a seed of its own)."""
    out = tmp_path_factory.mktemp("ds") / "forest"
    args = ["dataset", "forest", "--out", str(out), "--frames", "23", "--seed", "77", "--scatter", "30"]
    args += ["--classes", "person,car,landing_pad", "--width", "160", "--height", "120", "--no-progress"]
    assert main(args) == 0
    return out


@pytest.mark.parametrize(
    "kw, field",
    [
        ({"epochs": 0}, "epochs"),
        ({"imgsz": (100, 320)}, "imgsz"),
        ({"imgsz": "big"}, "imgsz"),
        ({"crop": (100, 320)}, "crop"),
        ({"width": (8, 16)}, "width"),
        ({"lr": -1.0}, "lr"),
        ({"threads": True}, "threads"),
    ],
)
def test_config_errors_name_the_field(kw, field):
    with pytest.raises(ConfigError, match=field):
        TrainDetectorConfig(**kw)


def test_cli_usage_errors_exit_2(tmp_path, capsys, tiny_dataset):
    assert main(["train-detector", str(tmp_path / "none"), "--out", str(tmp_path / "m.onnx")]) == 2
    assert "data.yaml" in capsys.readouterr().err
    assert main(["train-detector", str(tiny_dataset), "--out", str(tmp_path / "m.onnx"), "--imgsz", "7x"]) == 2
    assert "--imgsz" in capsys.readouterr().err


class _Opens:
    """A pickle that, loaded without weights_only, would create a file (``open(path, "w")``)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self):
        return (open, (str(self.path), "w"))


def test_init_that_is_not_weights_exits_2_and_runs_nothing(tmp_path, tiny_dataset, capsys):
    torch = pytest.importorskip("torch")
    marker = tmp_path / "ran"
    text, evil = tmp_path / "text.pt", tmp_path / "evil.pt"
    text.write_text("not weights")
    torch.save({"x": _Opens(marker)}, evil)
    for init in (text, evil):
        args = ["train-detector", str(tiny_dataset), "--out", str(tmp_path / "m.onnx"), "--init", str(init)]
        assert main([*args, "--epochs", "1", "--threads", "1", "--no-progress"]) == 2
        assert "init weights" in capsys.readouterr().err
    assert not marker.exists()


def test_letterboxed_labels_follow_the_image(tiny_dataset):
    """Boxes are scaled into the 240 x 320 input as the image is: 160 x 120 doubled, no padding."""
    d = load_yolo_dataset([tiny_dataset], "train", (240, 320))
    label = sorted((tiny_dataset / "labels" / "train").glob("*.txt"))[0]
    rows = np.loadtxt(label, ndmin=2)
    expected = np.stack(
        [
            (rows[:, 1] - rows[:, 3] / 2) * 320,
            (rows[:, 2] - rows[:, 4] / 2) * 240,
            (rows[:, 1] + rows[:, 3] / 2) * 320,
            (rows[:, 2] + rows[:, 4] / 2) * 240,
        ],
        1,
    )
    np.testing.assert_allclose(d.boxes[0], expected, atol=1e-3)
    assert d.names == ("person", "car", "landing_pad") and d.images.shape[1:] == (240, 320, 3)


def test_data_yaml_naming_images_elsewhere_is_refused(tmp_path, tiny_dataset):
    """A data.yaml whose train: names images outside its folder (here another dataset's, whose labels this folder
    does not hold) is refused, not read as images without boxes."""
    import os

    import yaml

    folder = tmp_path / "elsewhere"
    folder.mkdir()
    doc = yaml.safe_load((tiny_dataset / "data.yaml").read_text())
    images = tiny_dataset / "images" / "train"
    for rel in (str(images), os.path.relpath(images, folder)):
        (folder / "data.yaml").write_text(yaml.safe_dump(doc | {"train": rel}))
        with pytest.raises(ValueError, match="images/train"):
            load_yolo_dataset([folder], "train", (240, 320))


def test_assignment_centre_sampling():
    torch = pytest.importorskip("torch")
    from cufund.perception import train_detector_model as tdm

    points, strides = tdm.grid_points((64, 96))
    boxes = torch.tensor([[10.0, 12.0, 50.0, 40.0], [70.0, 30.0, 73.0, 33.0]])  # a box, and one between centres
    a = tdm.assign(boxes, points, strides)
    pos = points[a == 0]
    assert len(pos) > 0
    assert (pos[:, 0] > 10).all() and (pos[:, 0] < 50).all() and (pos[:, 1] > 12).all() and (pos[:, 1] < 40).all()
    s = strides[a == 0]
    assert ((pos[:, 0] - 30).abs() < 2.5 * s).all() and ((pos[:, 1] - 26).abs() < 2.5 * s).all()
    (k,) = torch.nonzero(a == 1).flatten().tolist()  # the tiny box: the stride-8 cell holding its centre
    assert strides[k] == 8 and points[k].tolist() == [68.0, 28.0]
    assert (tdm.assign(torch.zeros((0, 4)), points, strides) == -1).all()


def test_onnx_output_equals_torch_inference_on_20_images(tmp_path, tiny_dataset):
    torch = pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from cufund.perception import train_detector_model as tdm
    from cufund.perception.onnx_detector import OnnxDetector
    from cufund.perception.train_detector import export_onnx

    cfg = TrainDetectorConfig(imgsz=(240, 320))
    torch.manual_seed(3)
    model = tdm.Detector(3, cfg.width, cfg.depth)
    with torch.no_grad():  # running statistics that are not the identity, as after training
        for m in model.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-0.2, 0.2)
                m.running_var.uniform_(0.5, 2.0)
    model.eval()
    path = tmp_path / "m.onnx"
    export_onnx(model, path, ("person", "car", "landing_pad"), cfg, {})
    det = OnnxDetector(path, nthreads=1)
    assert det.names == ("person", "car", "landing_pad") and det.input_hw == (240, 320)
    wrapper = tdm.ExportWrapper(model, (240, 320)).eval()
    data = load_yolo_dataset([tiny_dataset], "train", (240, 320))
    assert len(data.images) >= 20
    for img in data.images[:20]:
        x = np.ascontiguousarray(img.transpose(2, 0, 1)[None], dtype=np.float32) / np.float32(255)
        ours = det.raw(x)[0]
        with torch.no_grad():
            ref = wrapper(torch.from_numpy(x)).numpy()
        assert ours.shape == ref.shape == (1, 4 + 3, 30 * 40 + 15 * 20)
        np.testing.assert_allclose(ours, ref, rtol=1e-4, atol=1e-3)


def test_train_detector_end_to_end(tmp_path, tiny_dataset, capsys):
    """Two epochs on 20 images: the command exports a model the onnx_detector runs, and a summary beside it
    whose loss went down."""
    pytest.importorskip("torch")
    pytest.importorskip("onnx")
    from cufund.perception.onnx_detector import OnnxDetector

    out = tmp_path / "m.onnx"
    args = ["train-detector", str(tiny_dataset), "--out", str(out), "--epochs", "3", "--imgsz", "128,160"]
    assert main([*args, "--seed", "1", "--threads", "1", "--no-progress"]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["classes"] == ["person", "car", "landing_pad"] and summary["images"] == 20
    losses = [h["loss"] for h in summary["history"]]
    assert losses[-1] < losses[0]
    det = OnnxDetector(out)
    assert det.input_hw == (128, 160) and det.names == ("person", "car", "landing_pad")
    image = np.zeros((120, 160, 3), np.uint8)
    assert len(det.detect(image).boxes_xyxy.shape) == 2

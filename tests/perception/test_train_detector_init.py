"""`cufund train-detector --init MODEL.onnx` (cufund.perception.train_detector_init): a model the command exported,
whose batch normalisations the export folded away, is loaded back as the same network (its outputs equal the
file's under onnxruntime), its re-chosen batch normalisations keep a training batch's activations close to the
exported network's, fine-tuning from it runs, and files that do not fit are refused by name. Skipped without torch
and onnx (the detect-train extra)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cufund.apps.cli import main
from cufund.perception.train_detector import TrainDetectorConfig, export_onnx, load_yolo_dataset

torch = pytest.importorskip("torch")
onnx = pytest.importorskip("onnx")

from cufund.perception import train_detector_model as tdm  # noqa: E402 - needs torch
from cufund.perception.onnx_detector import OnnxDetector  # noqa: E402
from cufund.perception.train_detector_init import load_exported_weights  # noqa: E402

CLASSES = ("person", "car", "landing_pad")
HW = (128, 160)


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ds") / "forest"
    args = ["dataset", "forest", "--out", str(out), "--frames", "12", "--seed", "78", "--scatter", "30"]
    args += ["--classes", ",".join(CLASSES), "--width", "160", "--height", "120", "--no-progress"]
    assert main(args) == 0
    return out


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """A model with batch normalisations far from the identity (as after training), exported."""
    torch.manual_seed(5)
    cfg = TrainDetectorConfig(imgsz=HW)
    model = tdm.Detector(len(CLASSES), cfg.width, cfg.depth)
    with torch.no_grad():
        for m in model.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-0.3, 0.3)
                m.running_var.uniform_(0.3, 3.0)
                m.weight.uniform_(0.5, 1.5)
                m.bias.uniform_(-0.2, 0.2)
    model.eval()
    path = tmp_path_factory.mktemp("m") / "m.onnx"
    export_onnx(model, path, CLASSES, cfg, {})
    return path


def _inputs(dataset: Path) -> np.ndarray:
    return load_yolo_dataset([dataset], "train", HW).images


def test_loaded_model_is_the_exported_network(tiny_dataset, exported):
    images = _inputs(tiny_dataset)
    model = tdm.Detector(len(CLASSES))
    load_exported_weights(model, exported, images[:6])
    assert model.training  # left as it was
    wrapper = tdm.ExportWrapper(model, HW).eval()
    det = OnnxDetector(exported, nthreads=1)
    for img in images[6:]:  # images other than the calibration ones
        x = np.ascontiguousarray(img.transpose(2, 0, 1)[None], dtype=np.float32) / np.float32(255)
        with torch.no_grad():
            ours = wrapper(torch.from_numpy(x)).numpy()
        np.testing.assert_allclose(ours, det.raw(x)[0], rtol=1e-4, atol=2e-3)
    # and exported again, the same file's outputs
    model.eval()
    again = exported.parent / "again.onnx"
    export_onnx(model, again, CLASSES, TrainDetectorConfig(imgsz=HW), {})
    x = np.ascontiguousarray(images[:2].transpose(0, 3, 1, 2), dtype=np.float32) / np.float32(255)
    ref = OnnxDetector(exported, nthreads=1)
    new = OnnxDetector(again, nthreads=1)
    np.testing.assert_allclose(new.raw(x[:1])[0], ref.raw(x[:1])[0], rtol=1e-4, atol=2e-3)


def test_train_mode_starts_near_the_exported_network(tiny_dataset, exported):
    """In train mode batch normalisation uses the batch's statistics: with the calibrated layers a batch of the
    calibration images gives nearly the eval outputs, while the naive choice (the folded weights with the identity
    batch normalisation) gives something else."""
    images = _inputs(tiny_dataset)[:8]
    x = torch.from_numpy(np.ascontiguousarray(images.transpose(0, 3, 1, 2))).float() / 255.0
    model = tdm.Detector(len(CLASSES))
    load_exported_weights(model, exported, images)
    model.eval()
    with torch.no_grad():
        ref = torch.cat([torch.cat(p, 1).flatten(1) for p in model(x)], 1)
        model.train()
        calibrated = torch.cat([torch.cat(p, 1).flatten(1) for p in model(x)], 1)
        for m in model.modules():  # the naive choice: the identity plus the folded bias
            if isinstance(m, torch.nn.BatchNorm2d):
                m.weight.fill_(1.0)
                m.bias.sub_(m.running_mean)
        naive = torch.cat([torch.cat(p, 1).flatten(1) for p in model(x)], 1)
    err_cal = float((calibrated - ref).abs().mean())
    err_naive = float((naive - ref).abs().mean())
    assert err_cal < 1e-3 < 0.1 * err_naive


def test_fine_tuning_from_an_exported_model_runs(tmp_path, tiny_dataset, exported):
    out = tmp_path / "tuned.onnx"
    args = ["train-detector", str(tiny_dataset), "--out", str(out), "--epochs", "1", "--imgsz", "128,160"]
    assert main([*args, "--init", str(exported), "--threads", "1", "--no-progress"]) == 0
    assert OnnxDetector(out).names == CLASSES


def test_files_that_do_not_fit_are_refused(tmp_path, tiny_dataset, exported, capsys):
    other = tmp_path / "wide.onnx"
    cfg = TrainDetectorConfig(imgsz=HW, width=(16, 32, 64))
    export_onnx(tdm.Detector(len(CLASSES), cfg.width).eval(), other, CLASSES, cfg, {})
    swapped = tmp_path / "swapped.onnx"  # same network, the classes in another order
    export_onnx(tdm.Detector(3).eval(), swapped, ("car", "person", "landing_pad"), TrainDetectorConfig(imgsz=HW), {})
    two = tmp_path / "two.onnx"
    export_onnx(tdm.Detector(2).eval(), two, ("person", "car"), TrainDetectorConfig(imgsz=HW), {})
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"\x08\x07not a model")
    external = tmp_path / "external.onnx"
    proto = onnx.load(str(exported))
    t = proto.graph.initializer[0]
    t.data_location = onnx.TensorProto.EXTERNAL
    entry = t.external_data.add()
    entry.key, entry.value = "location", "/etc/passwd"
    t.ClearField("raw_data")
    onnx.save(proto, str(external))
    for path, says in (
        (other, "convolution 0"),
        (swapped, "the datasets' classes"),
        (two, "convolution"),
        (garbage, "not an ONNX model"),
        (external, "external file"),
    ):
        args = ["train-detector", str(tiny_dataset), "--out", str(tmp_path / "m.onnx"), "--init", str(path)]
        assert main([*args, "--epochs", "1", "--imgsz", "128,160", "--threads", "1", "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert "init weights" in err and says in err, err
    assert not (tmp_path / "m.onnx").exists()

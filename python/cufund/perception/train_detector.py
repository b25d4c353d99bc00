"""Trains a small detector from scratch on ``cufund dataset`` output and exports it to ONNX (``cufund
train-detector``).

Plain torch on the CPU (no torchvision, no ultralytics: PyPI's torchvision does not load beside the CPU torch
wheel, and ultralytics needs it); the network, assignment and loss are in
:mod:`cufund.perception.train_detector_model`. The exported model has ultralytics' YOLOv8 layout (one output
(1, 4 + nc, N): centre u, centre v, width, height in input pixels, then sigmoid class scores) and the metadata
``names``, ``imgsz``, ``stride`` and ``task``, so :class:`cufund.perception.onnx_detector.OnnxDetector` runs it
with onnxruntime alone. Images are letterboxed to the input size exactly as the detector does at inference
(:class:`cufund.perception.letterbox.Letterbox`).

torch and onnx are imported inside the functions (the ``detect-train`` extra); importing this module needs
neither.
"""

from __future__ import annotations

import dataclasses
import json
import pickle
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, load_yaml

from .letterbox import Letterbox
from .onnx_detector import load_class_names

__all__ = ["TrainDetectorConfig", "load_yolo_dataset", "train_detector"]


@dataclass(frozen=True)
class TrainDetectorConfig:
    epochs: int = 30
    """Passes over the training images [-]."""
    imgsz: tuple[int, int] = (240, 320)
    """Input (height, width) [px], multiples of 16 (240 x 320: a 640 x 480 image halved, no padding)."""
    batch: int = 16
    """Images per step [-]."""
    lr: float = 2e-3
    """Peak learning rate of AdamW (one-cycle: linear warm-up over the first epoch, cosine decay) [-]."""
    weight_decay: float = 5e-4
    """AdamW's weight decay [-]."""
    seed: int = 0
    """Seed of the weights' initialisation, the shuffling and the augmentation."""
    threads: int = 2
    """torch's intra-op threads [-]."""
    width: tuple[int, int, int] = (24, 48, 96)
    """Channels at strides 4, 8 and 16 [-]."""
    depth: int = 1
    """Residual blocks after the stride-8 and the stride-16 stage [-]."""
    crop: tuple[int, int] | None = (160, 224)
    """Train on random crops of this (height, width) of the letterboxed images [px], multiples of 16 (the network
    is convolutional: the exported model still takes ``imgsz``), each side at most ``imgsz``'s; None: whole images. Cuts the training time by the
    pixel ratio; a box cut by the crop is clipped to it (as the dataset clips boxes at the image's edges) and
    dropped when less than 4 px or less than a third of it remains."""
    flip: bool = True
    """Random horizontal flips."""
    colour_jitter: float = 0.2
    """Random brightness and contrast factors in [1 - j, 1 + j] [-]."""

    def __post_init__(self) -> None:
        for name, lo, hi in (
            ("epochs", 1, 10_000),
            ("batch", 1, 4096),
            ("seed", 0, 2**31 - 1),
            ("threads", 1, 256),
            ("depth", 0, 8),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ConfigError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
        try:
            h, w = (int(x) for x in self.imgsz)
        except (TypeError, ValueError):
            raise ConfigError(f"imgsz must be (height, width) [px], got {self.imgsz!r}") from None
        if not (16 <= h <= 4096 and 16 <= w <= 4096 and h % 16 == 0 and w % 16 == 0):
            raise ConfigError(f"imgsz must be (height, width), each a multiple of 16 in [16, 4096], got {self.imgsz!r}")
        object.__setattr__(self, "imgsz", (h, w))
        if self.crop is not None:
            try:
                ch, cw = (int(x) for x in self.crop)
            except (TypeError, ValueError):
                raise ConfigError(f"crop must be (height, width) [px] or None, got {self.crop!r}") from None
            if not (16 <= ch <= 4096 and 16 <= cw <= 4096 and ch % 16 == 0 and cw % 16 == 0):
                raise ConfigError(
                    f"crop must be (height, width), each a multiple of 16 in [16, 4096], got {self.crop!r}"
                )
            object.__setattr__(self, "crop", (min(ch, h), min(cw, w)))  # no larger than the input
        if len(self.width) != 3 or not all(isinstance(c, int) and 1 <= c <= 1024 for c in self.width):
            raise ConfigError(f"width must be three channel counts in [1, 1024], got {self.width!r}")
        object.__setattr__(self, "width", tuple(self.width))
        for fname, flo, fhi in (("lr", 1e-6, 1.0), ("weight_decay", 0.0, 1.0), ("colour_jitter", 0.0, 0.9)):
            v = getattr(self, fname)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not flo <= v <= fhi:
                raise ConfigError(f"{fname} must be a number in [{flo}, {fhi}], got {v!r}")


@dataclass
class YoloImages:
    """Letterboxed images and their boxes, in the model's input pixels."""

    images: np.ndarray
    """(n, H, W, 3) uint8 RGB."""
    classes: list[np.ndarray]
    """Per image (k,) int64 class ids."""
    boxes: list[np.ndarray]
    """Per image (k, 4) float32 (u_min, v_min, u_max, v_max) [px]."""
    names: tuple[str, ...]


def _read_png(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def load_yolo_dataset(
    folders: Sequence[str | Path], split: str, imgsz: tuple[int, int], limit: int | None = None
) -> YoloImages:
    """The ``split`` ("train" or "val") images of YOLO-layout dataset folders (each with ``data.yaml``, as ``cufund
    dataset`` writes), letterboxed to ``imgsz``. All folders must have the same class names. Images and labels are
    read from the folder's ``images/<split>`` and ``labels/<split>`` (the layout ``cufund dataset`` writes); a
    ``data.yaml`` whose ``<split>`` names another place (outside the folder, or images whose labels would not be
    found) is refused."""
    if split not in ("train", "val"):
        raise ValueError(f"split must be 'train' or 'val', got {split!r}")
    names: tuple[str, ...] | None = None
    files: list[tuple[Path, Path]] = []
    for folder in folders:
        root = Path(folder)
        data = root / "data.yaml"
        if not data.is_file():
            raise ValueError(f"dataset {str(root)!r} has no data.yaml (write one with `cufund dataset`)")
        these = load_class_names(data)
        if names is not None and these != names:
            raise ValueError(f"dataset {str(root)!r} has classes {list(these)}, the first had {list(names)}")
        names = these
        doc = load_yaml(data)
        rel = doc.get(split, f"images/{split}") if isinstance(doc, dict) else f"images/{split}"
        if Path(str(rel)) != Path("images", split):
            raise ValueError(
                f"{data}: {split}: must be images/{split} (the layout `cufund dataset` writes), got {rel!r}"
            )
        for image in sorted((root / "images" / split).glob("*.png")):
            label = root / "labels" / split / (image.stem + ".txt")
            files.append((image, label))
    if names is None:
        raise ValueError("no dataset folder given")
    if limit is not None:
        files = files[:limit]
    if not files:
        raise ValueError(f"no {split} images in {[str(f) for f in folders]}")
    h, w = imgsz
    images = np.empty((len(files), h, w, 3), np.uint8)
    classes, boxes = [], []
    for i, (image_path, label_path) in enumerate(files):
        img = _read_png(image_path)
        box = Letterbox.fit(img.shape[:2], imgsz)
        images[i] = box.apply(img)
        rows = np.zeros((0, 5))
        if label_path.is_file():
            text = label_path.read_text()
            rows = np.array([[float(x) for x in line.split()] for line in text.splitlines() if line.strip()])
            rows = rows.reshape(-1, 5)
        if len(rows) and (np.any(rows[:, 0] < 0) or np.any(rows[:, 0] >= len(names)) or not np.isfinite(rows).all()):
            raise ValueError(f"{label_path}: class ids must be in [0, {len(names)}) and numbers finite")
        sh, sw = img.shape[:2]
        cx, cy, bw, bh = rows[:, 1] * sw, rows[:, 2] * sh, rows[:, 3] * sw, rows[:, 4] * sh
        xyxy = np.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2], 1)
        gx, gy = box.gain_xy
        xyxy = xyxy * np.array([gx, gy, gx, gy]) + np.array([box.left, box.top, box.left, box.top])
        classes.append(rows[:, 0].astype(np.int64))
        boxes.append(xyxy.astype(np.float32))
    return YoloImages(images, classes, boxes, names)


def _augment(
    rng: np.random.Generator, img: np.ndarray, classes: np.ndarray, boxes: np.ndarray, cfg: TrainDetectorConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    b = boxes.copy()
    if cfg.crop is not None:
        (ch, cw), (h, w) = cfg.crop, img.shape[:2]
        if len(b) and rng.random() < 0.8:  # mostly around a box, so that most crops hold one
            k = int(rng.integers(len(b)))
            cu, cv = (b[k, 0] + b[k, 2]) / 2, (b[k, 1] + b[k, 3]) / 2
            u0 = int(np.clip(cu - rng.uniform(0.1, 0.9) * cw, 0, w - cw))
            v0 = int(np.clip(cv - rng.uniform(0.1, 0.9) * ch, 0, h - ch))
        else:
            u0, v0 = int(rng.integers(w - cw + 1)), int(rng.integers(h - ch + 1))
        img = img[v0 : v0 + ch, u0 : u0 + cw]
        area = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
        b = b - np.array([u0, v0, u0, v0], np.float32)
        b[:, [0, 2]] = b[:, [0, 2]].clip(0, cw)
        b[:, [1, 3]] = b[:, [1, 3]].clip(0, ch)
        bw, bh = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
        keep = (bw >= 4) & (bh >= 4) & (bw * bh >= area / 3)
        b, classes = b[keep], classes[keep]
    x = img.astype(np.float32) / 255.0
    if cfg.flip and rng.random() < 0.5:
        x = x[:, ::-1]
        w = img.shape[1]
        b[:, [0, 2]] = w - b[:, [2, 0]]
    if cfg.colour_jitter > 0:
        j = cfg.colour_jitter
        gain, contrast = rng.uniform(1 - j, 1 + j), rng.uniform(1 - j, 1 + j)
        mean = x.mean()
        x = np.clip((x - mean) * contrast + mean * gain, 0.0, 1.0)
    return np.ascontiguousarray(x.transpose(2, 0, 1)), classes, b


CALIBRATION_IMAGES = 64
"""Training images (drawn with the run's seed) whose statistics set the batch normalisations of a model started
from an exported ONNX (:mod:`cufund.perception.train_detector_init`)."""


def train_detector(
    datasets: Sequence[str | Path],
    out: str | Path,
    cfg: TrainDetectorConfig,
    log: Callable[[str], None] | None = None,
    init: str | Path | None = None,
) -> dict[str, Any]:
    """Trains on the ``train`` split of ``datasets``, exports ``out`` (ONNX) and returns a summary (losses per
    epoch, time, the config). The torch weights are saved beside ``out`` (``.pt``) after every epoch; ``init``: such
    a file to start from (a run continued), or a ``.onnx`` this function exported (fine-tuning a shipped model:
    :mod:`cufund.perception.train_detector_init`). Needs torch and onnx (``pip install 'cufund[detect-train]'``)."""
    out = Path(out)
    if out.suffix != ".onnx":
        raise ValueError(f"--out must name a .onnx file, got {str(out)!r}")
    for folder in datasets:  # usage errors first, with or without torch
        if not (Path(folder) / "data.yaml").is_file():
            raise ValueError(f"dataset {str(folder)!r} has no data.yaml (write one with `cufund dataset`)")
    try:
        import torch
    except ImportError:
        raise ValueError("cufund train-detector needs torch and onnx: pip install 'cufund[detect-train]'") from None
    from . import train_detector_model as tdm

    out.parent.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    data = load_yolo_dataset(datasets, "train", cfg.imgsz)
    n = len(data.images)
    if log:
        log(f"{n} training images, classes {list(data.names)}, input {cfg.imgsz[0]} x {cfg.imgsz[1]}")
    model = tdm.Detector(len(data.names), cfg.width, cfg.depth)
    weights = out.with_suffix(".pt")
    if init is not None and Path(init).suffix.lower() == ".onnx":  # a model this command exported: BN refolded
        from .onnx_detector import OnnxDetector
        from .train_detector_init import load_exported_weights

        load_exported_weights(model, init, data.images[rng.permutation(n)[:CALIBRATION_IMAGES]])
        # read as weights first (external-data tensors refused there), then its classes checked
        try:
            init_names = OnnxDetector(init, nthreads=1).names
        except (ValueError, OSError) as e:  # not a detector the onnx_detector runs: refused
            raise ValueError(f"init weights {str(init)!r} are not a detection model: {str(e)[:200]}") from None
        if tuple(init_names) != tuple(data.names):  # same count, other classes or order: the heads would mislabel
            raise ValueError(
                f"init weights {str(init)!r} detect {list(init_names)}, the datasets' classes are {list(data.names)}"
            )
    elif init is not None:
        try:
            model.load_state_dict(torch.load(Path(init), map_location="cpu", weights_only=True))
        except (OSError, RuntimeError, KeyError, EOFError, pickle.UnpicklingError) as e:  # weights_only: not weights
            raise ValueError(f"init weights {str(init)!r} do not fit this model: {str(e)[:200]}") from None
    points, strides = tdm.grid_points(cfg.crop or cfg.imgsz)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    steps_per_epoch = (n + cfg.batch - 1) // cfg.batch
    total = steps_per_epoch * cfg.epochs
    warm = steps_per_epoch

    def lr_at(step: int) -> float:
        if step < warm:
            return cfg.lr * (step + 1) / warm
        return cfg.lr * 0.5 * (1.0 + np.cos(np.pi * (step - warm) / max(total - warm, 1))) + cfg.lr * 0.01

    history = []
    step = 0
    model.train()
    for epoch in range(cfg.epochs):
        order = rng.permutation(n)
        sums = {"loss": 0.0, "cls": 0.0, "box": 0.0}
        t0 = time.perf_counter()
        for s in range(steps_per_epoch):
            idx = order[s * cfg.batch : (s + 1) * cfg.batch]
            xs, targets = [], []
            for i in idx:
                x, c, b = _augment(rng, data.images[i], data.classes[i], data.boxes[i], cfg)
                xs.append(x)
                targets.append((torch.from_numpy(c), torch.from_numpy(b)))
            for g in opt.param_groups:
                g["lr"] = lr_at(step)
            reg, cls = tdm.flatten(model(torch.from_numpy(np.stack(xs))))
            loss, parts = tdm.detection_loss(reg, cls, targets, points, strides)
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
            opt.step()
            step += 1
            sums["loss"] += float(loss.detach())
            sums["cls"] += parts["cls"]
            sums["box"] += parts["box"]
        row = {k: v / steps_per_epoch for k, v in sums.items()} | {"epoch": epoch + 1}
        row["seconds"] = time.perf_counter() - t0
        history.append(row)
        torch.save(model.state_dict(), weights)  # every epoch: a run stopped early can be exported or resumed
        if log:
            log(
                f"epoch {epoch + 1}/{cfg.epochs}: loss {row['loss']:.3f} (cls {row['cls']:.3f}, box {row['box']:.3f}) "
                f"{row['seconds']:.0f} s"
            )
    model.eval()
    extra = {"datasets": [str(Path(d)) for d in datasets], "images": n, "init": None if init is None else str(init)}
    export_onnx(model, out, data.names, cfg, extra)
    summary = {
        "out": str(out),
        "classes": list(data.names),
        "images": n,
        "seconds": time.perf_counter() - t_start,
        "final_loss": history[-1]["loss"],
        "config": dataclasses.asdict(cfg),
        "history": history,
    }
    return summary


def export_onnx(model: Any, out: Path, names: tuple[str, ...], cfg: TrainDetectorConfig, extra: dict[str, Any]) -> None:
    """Writes ``model`` (a :class:`~cufund.perception.train_detector_model.Detector` in eval mode) to ``out`` in
    the YOLOv8 export layout with its metadata."""
    import onnx
    import torch

    from . import train_detector_model as tdm

    wrapper = tdm.ExportWrapper(model, cfg.imgsz).eval()
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter (no onnxscript needed) warns that it is legacy
        path = Path(tmp) / "model.onnx"
        torch.onnx.export(
            wrapper,
            (torch.zeros(1, 3, *cfg.imgsz),),
            str(path),
            dynamo=False,
            opset_version=17,
            input_names=["images"],
            output_names=["output0"],
            do_constant_folding=True,
        )
        proto = onnx.load(str(path))
    meta = {
        "names": repr(dict(enumerate(names))),
        "imgsz": repr(list(cfg.imgsz)),
        "stride": repr(max(tdm.STRIDES)),
        "task": "detect",
        "author": "cufund train-detector",
        "train_config": json.dumps(dataclasses.asdict(cfg) | extra),
    }
    del proto.metadata_props[:]
    for k, v in meta.items():
        p = proto.metadata_props.add()
        p.key, p.value = k, v
    out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(proto, str(out))

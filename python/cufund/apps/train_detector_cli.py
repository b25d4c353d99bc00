"""``cufund train-detector DATASET [DATASET ...] --out model.onnx``: trains a small detector from scratch on
``cufund dataset`` folders (plain torch on the CPU) and exports it to ONNX in the YOLOv8 layout the
``onnx_detector`` runs (:mod:`cufund.perception.train_detector`); its torch weights go beside it (``.pt``, every
epoch). Needs the ``detect-train`` extra (torch, onnx).
Exit codes: 0 trained and exported, 2 invalid configuration or usage (a message naming the field), 130
interrupted."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cufund.core.config import ConfigError, load_yaml

__all__ = ["add_arguments", "parse_imgsz", "run"]


def parse_imgsz(text: str) -> tuple[int, int]:
    """``"320"`` (square), ``"240,320"`` or ``"240x320"`` -> (height, width)."""
    parts = text.lower().replace("x", ",").split(",")
    try:
        values = [int(p) for p in parts]
    except ValueError:
        raise ConfigError(f"--imgsz must be N or H,W in px, got {text!r}") from None
    if len(values) == 1:
        return values[0], values[0]
    if len(values) == 2:
        return values[0], values[1]
    raise ConfigError(f"--imgsz must be N or H,W in px, got {text!r}")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("datasets", nargs="+", type=Path, help="dataset folders written by `cufund dataset` (same classes)")
    p.add_argument("--out", type=Path, required=True, help="the ONNX model written (.onnx); a .json summary beside it")
    p.add_argument("--config", type=Path, default=None, help="a YAML whose 'train' mapping holds config keys")
    p.add_argument("--epochs", type=int, default=None, help="passes over the training images (default 30)")
    p.add_argument("--imgsz", default=None, help="input size H,W or N [px], multiples of 16 (default 240,320)")
    p.add_argument("--seed", type=int, default=None, help="seed of the weights, shuffling and augmentation (default 0)")
    p.add_argument("--threads", type=int, default=None, help="torch threads (default 2)")
    p.add_argument(
        "--init",
        type=Path,
        default=None,
        help="weights to start from: the .pt saved beside a model, or a .onnx this command exported "
        "(e.g. a shipped model, to fine-tune it)",
    )
    p.add_argument("--no-progress", action="store_true", help="no per-epoch lines")


def run(args: argparse.Namespace) -> int:
    try:
        from cufund.perception.train_detector import TrainDetectorConfig, train_detector

        keys: dict = {}
        if args.config is not None:
            doc = load_yaml(args.config)
            train = doc.get("train") if isinstance(doc, dict) else None
            if not isinstance(train, dict):
                raise ConfigError(f"{args.config}: expected a mapping with a 'train' mapping of config keys")
            known = set(TrainDetectorConfig.__dataclass_fields__)
            unknown = sorted(set(train) - known)
            if unknown:
                raise ConfigError(f"{args.config}: train: unknown keys {unknown}; known: {sorted(known)}")
            keys.update(train)
        for name in ("epochs", "seed", "threads"):
            if getattr(args, name) is not None:
                keys[name] = getattr(args, name)
        if args.imgsz is not None:
            keys["imgsz"] = parse_imgsz(args.imgsz)
        for name in ("imgsz", "crop", "width"):
            if isinstance(keys.get(name), list):
                keys[name] = tuple(keys[name])
        cfg = TrainDetectorConfig(**keys)
        log = None if args.no_progress else (lambda m: print(m, file=sys.stderr, flush=True))
        summary = train_detector(args.datasets, args.out, cfg, log=log, init=args.init)
    except KeyboardInterrupt:
        print("cufund train-detector: interrupted", file=sys.stderr)
        return 130
    except (ConfigError, ValueError, TypeError, OSError) as e:
        print(f"cufund train-detector: {e}", file=sys.stderr)
        return 2
    Path(args.out).with_suffix(".json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    print(json.dumps({k: summary[k] for k in ("out", "classes", "images", "seconds", "final_loss")}, indent=2))
    return 0

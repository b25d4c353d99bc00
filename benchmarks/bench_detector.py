"""Latency of the shipped detection models (issue 26, target <= 25 ms per 640 x 480 frame on 2 cores).

For each model in ``cufund.perception.models``, renders a few 640 x 480 frames of its held-out scenario (``cufund
dataset``, a seed not used in training), then times :meth:`OnnxDetector.detect` (letterbox, onnxruntime, decoding,
NMS: what the ``onnx_detector`` component does per image) with onnxruntime on 1 and on 2 intra-op threads, and
prints the median and the 95th percentile per frame, and the model's size.
Run: ``.venv/bin/python benchmarks/bench_detector.py [--repeats N] [--frames F]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from cufund.apps.cli import main as cufund_main
from cufund.perception.models import SHIPPED, model_path
from cufund.perception.onnx_detector import OnnxDetector

SCENES = {
    "people_cars_pads": ["forest", "--seed", "9101", "--scatter", "40", "--classes", "person,car,landing_pad"],
    "frames_gates": ["tunnel", "--seed", "9102", "--scatter", "30", "--classes", "tunnel_frame,gate"],
}


def frames_of(name: str, n: int, tmp: Path) -> list[np.ndarray]:
    out = tmp / name
    scenario, *rest = SCENES[name]
    with contextlib.redirect_stdout(io.StringIO()):
        code = cufund_main(["dataset", scenario, "--out", str(out), "--frames", str(n), "--no-progress", *rest])
    assert code == 0, f"cufund dataset failed for {name}"
    paths = sorted((out / "images").rglob("*.png"))
    return [np.asarray(Image.open(p).convert("RGB")) for p in paths]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10, help="passes over the frames per setting (default 10)")
    ap.add_argument("--frames", type=int, default=10, help="frames rendered per model (default 10)")
    args = ap.parse_args()
    print(f"{'model':<18} {'threads':>7} {'median ms':>10} {'p95 ms':>8} {'boxes/frame':>12} {'size MB':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in SHIPPED:
            images = frames_of(name, args.frames, Path(tmp))
            path = model_path(name)
            for threads in (1, 2):
                det = OnnxDetector(path, nthreads=threads)
                for img in images[:3]:  # warm-up
                    det.detect(img)
                times, boxes = [], []
                for _ in range(args.repeats):
                    for img in images:
                        r = det.detect(img)
                        times.append(r.latency_ms)
                        boxes.append(len(r))
                t = np.array(times)
                print(
                    f"{name:<18} {threads:>7} {np.median(t):>10.2f} {np.percentile(t, 95):>8.2f} "
                    f"{np.mean(boxes):>12.1f} {path.stat().st_size / 1e6:>8.2f}"
                )


if __name__ == "__main__":
    main()

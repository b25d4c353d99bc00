"""Letterboxing: an image scaled to fit a detector's fixed input size, aspect ratio kept, the rest padded.

The geometry is ultralytics' ``LetterBox(auto=False, center=True)`` (what its predictor does for an exported
model): the scale ``r = min(H_in / H, W_in / W)``, the scaled size rounded per side, the padding split in two
with ``round(d / 2 ∓ 0.1)``, grey 114. Resampling is bilinear with half-pixel centres (OpenCV's
``INTER_LINEAR`` in floating point: the same image to ±1 grey level).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PAD_VALUE = 114
"""Grey level of the padding (ultralytics' default)."""


@dataclass(frozen=True)
class Letterbox:
    """Where an image of ``src_hw`` lies in the letterboxed input of ``dst_hw``."""

    src_hw: tuple[int, int]
    """(height, width) of the original image [px]."""
    dst_hw: tuple[int, int]
    """(height, width) of the model's input [px]."""
    scaled_hw: tuple[int, int]
    """(height, width) of the scaled image inside the input [px]."""
    top: int
    """Padding rows above the scaled image [px]."""
    left: int
    """Padding columns left of the scaled image [px]."""

    @classmethod
    def fit(cls, src_hw: tuple[int, int], dst_hw: tuple[int, int]) -> Letterbox:
        h, w = int(src_hw[0]), int(src_hw[1])
        H, W = int(dst_hw[0]), int(dst_hw[1])
        if min(h, w, H, W) < 1:
            raise ValueError(f"image sizes must be >= 1 px, got source {src_hw} and input {dst_hw}")
        r = min(H / h, W / w)
        sh, sw = max(round(h * r), 1), max(round(w * r), 1)
        return cls((h, w), (H, W), (sh, sw), round((H - sh) / 2 - 0.1), round((W - sw) / 2 - 0.1))

    @property
    def gain_xy(self) -> tuple[float, float]:
        """Scale of the scaled image over the original, along u and along v [-]."""
        return self.scaled_hw[1] / self.src_hw[1], self.scaled_hw[0] / self.src_hw[0]

    def apply(self, image: np.ndarray) -> np.ndarray:
        """(h, w, 3) uint8 -> (H, W, 3) uint8 letterboxed image."""
        out = np.full((*self.dst_hw, image.shape[2]), PAD_VALUE, dtype=np.uint8)
        sh, sw = self.scaled_hw
        out[self.top : self.top + sh, self.left : self.left + sw] = resize_bilinear(image, (sh, sw))
        return out

    def boxes_to_source(self, boxes_xyxy: np.ndarray) -> np.ndarray:
        """(k, 4) boxes in input pixels -> the original image's pixels, clipped to it."""
        gx, gy = self.gain_xy
        b = np.array(boxes_xyxy, dtype=np.float64, copy=True).reshape(-1, 4)
        b[:, [0, 2]] = (b[:, [0, 2]] - self.left) / gx
        b[:, [1, 3]] = (b[:, [1, 3]] - self.top) / gy
        b[:, [0, 2]] = b[:, [0, 2]].clip(0, self.src_hw[1])
        b[:, [1, 3]] = b[:, [1, 3]].clip(0, self.src_hw[0])
        return b


def resize_bilinear(image: np.ndarray, size_hw: tuple[int, int]) -> np.ndarray:
    """(h, w, C) uint8 image resampled to ``size_hw`` bilinearly, pixel centres aligned (OpenCV's INTER_LINEAR)."""
    h, w = image.shape[:2]
    H, W = size_hw
    if (h, w) == (H, W):
        return image.copy()

    def axis(n_src: int, n_dst: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = (np.arange(n_dst) + 0.5) * (n_src / n_dst) - 0.5
        x = np.clip(x, 0.0, n_src - 1)
        i0 = np.floor(x).astype(np.int64)
        i1 = np.minimum(i0 + 1, n_src - 1)
        return i0, i1, (x - i0).astype(np.float32)

    y0, y1, fy = axis(h, H)
    x0, x1, fx = axis(w, W)
    img = image.astype(np.float32)
    rows = img[y0] * (1 - fy)[:, None, None] + img[y1] * fy[:, None, None]
    out = rows[:, x0] * (1 - fx)[None, :, None] + rows[:, x1] * fx[None, :, None]
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)

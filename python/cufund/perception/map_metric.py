"""Mean average precision of detections against ground-truth boxes, as COCO's evaluation computes it.

Per class, the detections of all images are ranked by score (stable: ties keep their input order); in its image,
each detection, best first, is matched to the not yet matched ground-truth box of its class with which it has the
highest IoU, when that IoU is at least the threshold (a true positive), else it is a false positive. Precision is
made non-increasing from the right (the envelope) and read at the 101 recall points 0, 0.01, ..., 1 (the first
ranked detection whose recall reaches the point; 0 when none does). AP is the mean of those 101 values; mAP the
mean of the per-class APs over the classes with at least one ground-truth box (pycocotools' ``COCOeval`` with
``iouThrs=[0.5]``, area "all", no crowd boxes; at most ``max_dets`` per image and class, highest scores first,
100 as COCO's).

Boxes are (u_min, v_min, u_max, v_max) in pixels; IoU is the area ratio of continuous boxes (COCO's ``bbox``, no
+1 pixel).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["APResult", "average_precision", "box_iou"]

RECALL_POINTS = np.linspace(0.0, 1.0, 101)
"""COCO's 101 recall thresholds."""


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, 4) x (m, 4) xyxy boxes -> (n, m) IoU."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    b = np.asarray(b, np.float64).reshape(-1, 4)
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(rb - lt, 0, None).prod(-1)
    area_a = np.clip(a[:, 2:] - a[:, :2], 0, None).prod(-1)
    area_b = np.clip(b[:, 2:] - b[:, :2], 0, None).prod(-1)
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


@dataclass(frozen=True)
class APResult:
    map: float
    """Mean of ``per_class`` over the classes with ground truth (nan when no class has any)."""
    per_class: dict[int, float]
    """AP per class id that has ground-truth boxes."""
    gt_count: dict[int, int]
    """Ground-truth boxes per class id."""


def _check(name: str, boxes: np.ndarray, n: int | None = None) -> np.ndarray:
    b = np.asarray(boxes, np.float64)
    if b.size == 0:
        return b.reshape(0, 4)
    if b.ndim != 2 or b.shape[1] != 4 or not np.isfinite(b).all():
        raise ValueError(f"{name} must be an (n, 4) array of finite (u_min, v_min, u_max, v_max), got {b.shape}")
    if n is not None and len(b) != n:
        raise ValueError(f"{name} has {len(b)} rows, its scores/classes {n}")
    return b


def average_precision(
    detections: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
    ground_truth: Sequence[tuple[np.ndarray, np.ndarray]],
    iou_threshold: float = 0.5,
    max_dets: int = 100,
) -> APResult:
    """COCO AP at one IoU threshold. ``detections``: per image (boxes (k, 4), scores (k,), class ids (k,));
    ``ground_truth``: per image (boxes (g, 4), class ids (g,)), in the same image order."""
    if len(detections) != len(ground_truth):
        raise ValueError(f"{len(detections)} images of detections, {len(ground_truth)} of ground truth")
    if not 0.0 < iou_threshold <= 1.0:
        raise ValueError(f"iou_threshold must be in (0, 1], got {iou_threshold!r}")
    dets, gts = [], []
    for i, ((db, ds, dc), (gb, gc)) in enumerate(zip(detections, ground_truth, strict=True)):
        ds = np.asarray(ds, np.float64).reshape(-1)
        dc = np.asarray(dc).reshape(-1).astype(np.int64)
        db = _check(f"detections[{i}] boxes", db, len(ds))
        if len(dc) != len(ds):
            raise ValueError(f"detections[{i}]: {len(ds)} scores, {len(dc)} classes")
        order = np.argsort(-ds, kind="mergesort")
        dets.append((db[order], ds[order], dc[order]))
        gc = np.asarray(gc).reshape(-1).astype(np.int64)
        gts.append((_check(f"ground_truth[{i}] boxes", gb, len(gc)), gc))
    classes = sorted({int(c) for _, gc in gts for c in gc})
    per_class: dict[int, float] = {}
    gt_count: dict[int, int] = {}
    for c in classes:
        scores, tps = [], []
        n_gt = 0
        for (db, ds, dc), (gb, gc) in zip(dets, gts, strict=True):
            d = dc == c
            g = gc == c
            n_gt += int(g.sum())
            b, s = db[d][:max_dets], ds[d][:max_dets]
            iou = box_iou(b, gb[g])
            matched = np.zeros(int(g.sum()), bool)
            tp = np.zeros(len(s), bool)
            for k in range(len(s)):  # already in descending score order
                best, best_j = min(iou_threshold, 1 - 1e-10), -1
                for j in range(len(matched)):
                    if matched[j] or iou[k, j] < best:
                        continue
                    best, best_j = iou[k, j], j
                if best_j >= 0:
                    matched[best_j] = True
                    tp[k] = True
            scores.append(s)
            tps.append(tp)
        gt_count[c] = n_gt
        s_all = np.concatenate(scores) if scores else np.zeros(0)
        tp_all = np.concatenate(tps) if tps else np.zeros(0, bool)
        order = np.argsort(-s_all, kind="mergesort")
        tp_all = tp_all[order]
        tp_cum = np.cumsum(tp_all)
        fp_cum = np.cumsum(~tp_all)
        recall = tp_cum / n_gt
        precision = tp_cum / (tp_cum + fp_cum + np.spacing(1))
        envelope = np.maximum.accumulate(precision[::-1])[::-1] if len(precision) else precision
        idx = np.searchsorted(recall, RECALL_POINTS, side="left")
        q = np.where(idx < len(envelope), envelope[np.minimum(idx, max(len(envelope) - 1, 0))], 0.0)
        per_class[c] = float(q.mean()) if len(envelope) else 0.0
    m = float(np.mean(list(per_class.values()))) if per_class else float("nan")
    return APResult(m, per_class, gt_count)

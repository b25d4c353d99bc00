"""Non-maximum suppression of scored boxes (greedy, per class, as torchvision's ``batched_nms``,
without its class-offset trick: boxes of different classes never meet)."""

from __future__ import annotations

import numpy as np


def box_iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """IoU of one (4,) xyxy box with each of (n, 4) xyxy boxes."""
    iw = np.clip(np.minimum(box[2], boxes[:, 2]) - np.maximum(box[0], boxes[:, 0]), 0, None)
    ih = np.clip(np.minimum(box[3], boxes[:, 3]) - np.maximum(box[1], boxes[:, 1]), 0, None)
    inter = iw * ih
    area = (box[2] - box[0]) * (box[3] - box[1])
    areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    return np.asarray(inter / np.maximum(area + areas - inter, np.finfo(np.float32).tiny))


def nms(
    boxes_xyxy: np.ndarray,
    scores: np.ndarray,
    iou_threshold: float,
    class_ids: np.ndarray | None = None,
    max_det: int = 300,
) -> np.ndarray:
    """Indices of the boxes kept, highest score first: a box is dropped when its IoU with a kept box of the same
    class (any class if ``class_ids`` is None) exceeds ``iou_threshold``."""
    boxes = np.asarray(boxes_xyxy, dtype=np.float32).reshape(-1, 4)
    scores = np.asarray(scores, dtype=np.float32).reshape(-1)
    if len(boxes) != len(scores):
        raise ValueError(f"boxes ({len(boxes)}) and scores ({len(scores)}) must have one row per box")
    classes = np.zeros(len(boxes), np.int64) if class_ids is None else np.asarray(class_ids).reshape(-1)
    if len(classes) != len(boxes):
        raise ValueError(f"class_ids ({len(classes)}) must have one entry per box ({len(boxes)})")
    order = np.argsort(-scores, kind="stable")
    keep: list[int] = []
    while len(order) and len(keep) < max_det:
        i = int(order[0])
        keep.append(i)
        rest = order[1:]
        same = classes[rest] == classes[i]
        drop = np.zeros(len(rest), dtype=bool)
        drop[same] = box_iou(boxes[i], boxes[rest[same]]) > iou_threshold
        order = rest[~drop]
    return np.asarray(keep, dtype=np.int64)

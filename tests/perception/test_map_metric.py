"""COCO-style AP@0.5 (cufund.perception.map_metric) against hand-computed cases and, when installed, against
faster-coco-eval (a reimplementation of pycocotools' COCOeval)."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.perception.map_metric import average_precision, box_iou


def _ap_101(recall_precision: list[tuple[float, float]]) -> float:
    """AP from (recall, precision) after each ranked detection, by COCO's rule written out by hand: the
    envelope, then at each of 101 recall points the envelope at the first detection reaching it."""
    env = [max(p for _, p in recall_precision[i:]) for i in range(len(recall_precision))]
    total = 0.0
    for r in np.linspace(0, 1, 101):
        reached = [k for k, (rec, _) in enumerate(recall_precision) if rec >= r - 1e-12]
        total += env[reached[0]] if reached else 0.0
    return total / 101


def test_box_iou_hand_computed():
    a = np.array([[0, 0, 10, 10]])
    b = np.array([[5, 0, 15, 10], [0, 0, 10, 10], [20, 20, 30, 30]])
    np.testing.assert_allclose(box_iou(a, b), [[50 / 150, 1.0, 0.0]])


def test_perfect_detections_give_one():
    gt = [(np.array([[0, 0, 10, 10], [20, 20, 40, 40]]), np.array([0, 1]))]
    det = [(np.array([[0, 0, 10, 10], [20, 20, 40, 40]]), np.array([0.9, 0.8]), np.array([0, 1]))]
    r = average_precision(det, gt)
    assert r.map == pytest.approx(1.0)
    assert r.per_class == {0: pytest.approx(1.0), 1: pytest.approx(1.0)}


def test_hand_computed_ranking():
    # one class, 3 ground-truth boxes over two images; ranked detections: TP, FP, TP, (miss one)
    gt = [
        (np.array([[0, 0, 10, 10], [50, 50, 60, 60]]), np.array([0, 0])),
        (np.array([[0, 0, 20, 20]]), np.array([0])),
    ]
    det = [
        (np.array([[0, 0, 10, 10], [100, 100, 110, 110]]), np.array([0.9, 0.8]), np.array([0, 0])),
        (np.array([[1, 1, 20, 20]]), np.array([0.7]), np.array([0])),  # IoU 361/400 > 0.5
    ]
    # after each: (recall, precision) = (1/3, 1), (1/3, 1/2), (2/3, 2/3)
    expected = _ap_101([(1 / 3, 1.0), (1 / 3, 0.5), (2 / 3, 2 / 3)])
    # recall points 0..0.33 -> 1 (34 points), 0.34..0.66 -> 2/3 (33 points), the rest 0
    assert expected == pytest.approx((34 * 1.0 + 33 * 2 / 3) / 101)
    assert average_precision(det, gt).map == pytest.approx(expected)


def test_duplicate_is_false_positive_and_threshold_inclusive():
    gt = [(np.array([[0, 0, 10, 10]]), np.array([0]))]
    # second box: IoU exactly 0.5 with the ground truth, but it is already matched -> FP
    det = [(np.array([[0, 0, 10, 10], [0, 0, 10, 5]]), np.array([0.9, 0.8]), np.array([0, 0]))]
    assert average_precision(det, gt).map == pytest.approx(1.0)  # the FP ranks after full recall
    det2 = [(np.array([[0, 0, 10, 5]]), np.array([0.9]), np.array([0]))]  # IoU 0.5 exactly: a match
    assert average_precision(det2, gt).map == pytest.approx(1.0)
    det3 = [(np.array([[0, 0, 10, 4.9]]), np.array([0.9]), np.array([0]))]  # IoU 0.49: none
    assert average_precision(det3, gt).map == pytest.approx(0.0)


def test_wrong_class_does_not_match_and_classes_without_gt_are_left_out():
    gt = [(np.array([[0, 0, 10, 10]]), np.array([0]))]
    det = [(np.array([[0, 0, 10, 10], [0, 0, 10, 10]]), np.array([0.95, 0.5]), np.array([2, 0]))]
    r = average_precision(det, gt)
    assert set(r.per_class) == {0}
    assert r.map == pytest.approx(1.0)


def test_bad_input_names_the_field():
    gt = [(np.array([[0, 0, 10, 10]]), np.array([0]))]
    with pytest.raises(ValueError, match="detections\\[0\\] boxes"):
        average_precision([(np.array([[0, 0, np.nan, 1]]), np.array([0.5]), np.array([0]))], gt)
    with pytest.raises(ValueError, match="images of detections"):
        average_precision([], gt)


def test_matches_faster_coco_eval_on_random_cases():
    fce = pytest.importorskip("faster_coco_eval")
    rng = np.random.default_rng(7)
    images, annotations, results = [], [], []
    dets, gts = [], []
    for i in range(30):
        g = int(rng.integers(0, 5))
        xy = rng.uniform(0, 200, (g, 2))
        wh = rng.uniform(5, 60, (g, 2))
        gb = np.concatenate([xy, xy + wh], 1)
        gc = rng.integers(0, 3, g)
        # detections: jittered copies of some ground truth, plus clutter
        keep = rng.random(g) < 0.8
        db = gb[keep] + rng.normal(0, 6, (int(keep.sum()), 4))
        db[:, 2:] = np.maximum(db[:, 2:], db[:, :2] + 1)
        dc = np.where(rng.random(int(keep.sum())) < 0.9, gc[keep], rng.integers(0, 3, int(keep.sum())))
        k = int(rng.integers(0, 4))
        cxy = rng.uniform(0, 200, (k, 2))
        db = np.concatenate([db, np.concatenate([cxy, cxy + rng.uniform(5, 60, (k, 2))], 1)])
        dc = np.concatenate([dc, rng.integers(0, 3, k)])
        ds = rng.uniform(0, 1, len(db)).round(6)
        gts.append((gb, gc))
        dets.append((db, ds, dc))
        images.append({"id": i + 1, "width": 300, "height": 300, "file_name": f"{i}.png"})
        for b, c in zip(gb, gc, strict=True):
            w, h = b[2] - b[0], b[3] - b[1]
            annotations.append(
                {
                    "id": len(annotations) + 1,
                    "image_id": i + 1,
                    "category_id": int(c) + 1,
                    "bbox": [float(b[0]), float(b[1]), float(w), float(h)],
                    "area": float(w * h),
                    "iscrowd": 0,
                }
            )
        for b, s, c in zip(db, ds, dc, strict=True):
            results.append(
                {
                    "image_id": i + 1,
                    "category_id": int(c) + 1,
                    "bbox": [float(b[0]), float(b[1]), float(b[2] - b[0]), float(b[3] - b[1])],
                    "score": float(s),
                }
            )
    coco_gt = fce.COCO()
    coco_gt.dataset = {
        "images": images,
        "annotations": annotations,
        "categories": [{"id": c + 1, "name": f"c{c}"} for c in range(3)],
    }
    coco_gt.createIndex()
    coco_dt = coco_gt.loadRes(results)
    ev = fce.COCOeval_faster(coco_gt, coco_dt, "bbox", print_function=lambda *a, **k: None)
    ev.params.iouThrs = np.array([0.5])
    ev.params.areaRng = [[0, 1e10]]
    ev.params.areaRngLbl = ["all"]
    ev.params.maxDets = [100]
    ev.evaluate()
    ev.accumulate()
    precision = ev.eval["precision"][0, :, :, 0, 0]  # (recall points, classes)
    ref = [float(np.mean(precision[:, k])) for k in range(3) if np.all(precision[:, k] > -1)]
    ours = average_precision(dets, gts)
    assert [ours.per_class[c] for c in sorted(ours.per_class)] == pytest.approx(ref, abs=1e-9)
    assert ours.map == pytest.approx(float(np.mean(ref)), abs=1e-9)

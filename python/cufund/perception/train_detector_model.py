"""The small anchor-free detector :mod:`cufund.perception.train_detector` trains, its target assignment and loss.

A YOLO-style network in plain torch (no torchvision): conv-BN-SiLU stages down to strides 8 and 16, a top-down
merge, and per level decoupled heads that give per cell the distances (left, top, right, bottom) from the cell's
centre to the box's edges and one logit per class. :class:`ExportWrapper` turns them into ultralytics' YOLOv8
export layout, (1, 4 + nc, N): centre u, centre v, width, height in input pixels, then the class scores after a
sigmoid — what :class:`cufund.perception.onnx_detector.OnnxDetector` reads.

Assignment (FCOS-style centre sampling): a cell is a positive of a box when its centre lies inside the box and
within :data:`CENTRE_RADIUS` strides of the box's centre, and the largest of its four distances to the edges is
within its level's range (:data:`LEVEL_RANGES_PX`); a cell claimed by several boxes takes the smallest. A box that
gets no cell (a small one between cell centres) takes the stride-8 cell holding its centre. Classification uses
the quality focal loss (GFL: the target of a positive is the IoU of its predicted box), regression the GIoU loss.

torch is imported by the caller (this module is imported only after torch is).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

STRIDES = (8, 16)
"""Strides of the two output levels [px]."""
LEVEL_RANGES_PX = ((0.0, 64.0), (32.0, 1e8))
"""Per level, the range of a positive cell's largest distance to its box's edges [px]."""
CENTRE_RADIUS = 2.5
"""A positive cell's centre is within this many strides of its box's centre (per axis) [-]."""


class ConvBnAct(nn.Sequential):
    def __init__(self, c_in: int, c_out: int, k: int = 3, s: int = 1) -> None:
        pad = (k - 1) // 2 if s == 1 or k % 2 else 0  # a k = s patch stem: no padding
        super().__init__(nn.Conv2d(c_in, c_out, k, s, pad, bias=False), nn.BatchNorm2d(c_out), nn.SiLU())


class Residual(nn.Module):
    def __init__(self, c: int) -> None:
        super().__init__()
        self.body = nn.Sequential(ConvBnAct(c, c, 3), ConvBnAct(c, c, 3))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.body(x)


class Head(nn.Module):
    """Head of one level: a shared 3 x 3 stage, then (B, 4, h, w) raw distances and (B, nc, h, w) class logits."""

    def __init__(self, c: int, nc: int, prior: float = 0.01) -> None:
        super().__init__()
        self.stem = ConvBnAct(c, c, 3)
        self.reg = nn.Conv2d(c, 4, 1)
        self.cls = nn.Conv2d(c, nc, 1)
        assert self.cls.bias is not None
        nn.init.constant_(self.cls.bias, float(-torch.log(torch.tensor((1 - prior) / prior))))

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        y = self.stem(x)
        return self.reg(y), self.cls(y)


class Detector(nn.Module):
    """Input (B, 3, H, W) RGB in [0, 1] (H, W multiples of 16). Output: per level (reg, cls) maps.

    A 4 x 4 stride-4 patch stem, then 3 x 3 stages to stride 8 (``width[1]`` channels) and 16 (``width[2]``), each
    followed by ``depth`` residual blocks of two 3 x 3 convolutions; the stride-16 features, reduced and upsampled, are added into the stride-8 ones by a 1 x 1 merge."""

    def __init__(self, nc: int, width: tuple[int, int, int] = (24, 48, 96), depth: int = 1) -> None:
        super().__init__()
        c2, c3, c4 = width
        self.nc = nc
        self.stem = ConvBnAct(3, c2, 4, 4)  # stride 4
        self.stage3 = nn.Sequential(
            ConvBnAct(c2, c3, 3, 2), ConvBnAct(c3, c3, 3), *(Residual(c3) for _ in range(depth))
        )  # stride 8
        self.stage4 = nn.Sequential(
            ConvBnAct(c3, c4, 3, 2), ConvBnAct(c4, c4, 3), *(Residual(c4) for _ in range(depth))
        )  # stride 16
        self.lat4 = ConvBnAct(c4, c3, 1)
        self.merge3 = ConvBnAct(2 * c3, c3, 1)
        self.head3 = Head(c3, nc)
        self.head4 = Head(c4, nc)

    def forward(self, x: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        c3 = self.stage3(self.stem(x))
        c4 = self.stage4(c3)
        p3 = self.merge3(torch.cat([c3, F.interpolate(self.lat4(c4), scale_factor=2.0, mode="nearest")], 1))
        return [self.head3(p3), self.head4(c4)]


def grid_points(hw: tuple[int, int], device: torch.device | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Cell centres (N, 2) [px] (u, v) of all levels, stride-8 cells first, row-major, and each one's stride (N,)."""
    pts, strides = [], []
    for s in STRIDES:
        h, w = hw[0] // s, hw[1] // s
        v, u = torch.meshgrid(torch.arange(h, device=device), torch.arange(w, device=device), indexing="ij")
        pts.append(torch.stack([u.reshape(-1), v.reshape(-1)], 1).float().add(0.5).mul(s))
        strides.append(torch.full((h * w,), float(s), device=device))
    return torch.cat(pts), torch.cat(strides)


def flatten(outputs: list[tuple[torch.Tensor, torch.Tensor]]) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-level maps -> (B, N, 4) raw distances and (B, N, nc) logits, in :func:`grid_points` order."""
    reg = torch.cat([r.flatten(2) for r, _ in outputs], 2).transpose(1, 2)
    cls = torch.cat([c.flatten(2) for _, c in outputs], 2).transpose(1, 2)
    return reg, cls


def decode(reg: torch.Tensor, points: torch.Tensor, strides: torch.Tensor) -> torch.Tensor:
    """(B, N, 4) raw distances -> (B, N, 4) boxes (u_min, v_min, u_max, v_max) [px]."""
    d = F.softplus(reg) * strides[None, :, None]
    return torch.cat([points[None] - d[..., :2], points[None] + d[..., 2:]], -1)


class ExportWrapper(nn.Module):
    """The detector with its decoding: (1, 3, H, W) -> (1, 4 + nc, N) as ultralytics exports YOLOv8."""

    points: torch.Tensor
    strides: torch.Tensor

    def __init__(self, model: Detector, hw: tuple[int, int]) -> None:
        super().__init__()
        self.model = model
        points, strides = grid_points(hw)
        self.register_buffer("points", points)
        self.register_buffer("strides", strides)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        reg, cls = flatten(self.model(x))
        b = decode(reg, self.points, self.strides)
        xywh = torch.cat([(b[..., :2] + b[..., 2:]) / 2, b[..., 2:] - b[..., :2]], -1)
        return torch.cat([xywh, cls.sigmoid()], -1).transpose(1, 2)


def box_iou_pairs(a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """IoU and GIoU of matching rows of (K, 4) xyxy boxes."""
    lt, rb = torch.maximum(a[:, :2], b[:, :2]), torch.minimum(a[:, 2:], b[:, 2:])
    inter = (rb - lt).clamp(min=0).prod(1)
    area_a = (a[:, 2:] - a[:, :2]).clamp(min=0).prod(1)
    area_b = (b[:, 2:] - b[:, :2]).clamp(min=0).prod(1)
    union = area_a + area_b - inter + 1e-9
    iou = inter / union
    hull = (torch.maximum(a[:, 2:], b[:, 2:]) - torch.minimum(a[:, :2], b[:, :2])).clamp(min=0).prod(1) + 1e-9
    return iou, iou - (hull - union) / hull


def assign(gt_boxes: torch.Tensor, points: torch.Tensor, strides: torch.Tensor) -> torch.Tensor:
    """For one image's (G, 4) xyxy boxes [px]: per cell the index of its box, -1 for a negative (N,)."""
    n = len(points)
    out = torch.full((n,), -1, dtype=torch.long)
    if len(gt_boxes) == 0:
        return out
    u, v = points[:, 0:1], points[:, 1:2]  # (N, 1)
    x1, y1, x2, y2 = (gt_boxes[:, i][None] for i in range(4))  # (1, G)
    ltrb = torch.stack([u - x1, v - y1, x2 - u, y2 - v], -1)  # (N, G, 4)
    inside = ltrb.min(-1).values > 0
    cu, cv = (x1 + x2) / 2, (y1 + y2) / 2
    r = CENTRE_RADIUS * strides[:, None]
    central = ((u - cu).abs() < r) & ((v - cv).abs() < r)
    reach = ltrb.max(-1).values
    lo = torch.tensor([r[0] for r in LEVEL_RANGES_PX])
    hi = torch.tensor([r[1] for r in LEVEL_RANGES_PX])
    level = torch.bucketize(strides, torch.tensor(STRIDES, dtype=strides.dtype))  # index of each cell's stride
    in_range = (reach >= lo[level][:, None]) & (reach <= hi[level][:, None])
    ok = inside & central & in_range
    area = ((x2 - x1) * (y2 - y1)).expand(n, -1)
    area = torch.where(ok, area, torch.full_like(area, float("inf")))
    best_area, best = area.min(1)
    out = torch.where(torch.isfinite(best_area), best, out)
    # a box with no cell takes the stride-8 cell holding its centre (when no other box has it)
    has = torch.zeros(len(gt_boxes), dtype=torch.bool)
    has[out[out >= 0].unique()] = True
    s0 = STRIDES[0]
    w0 = int(round(float(points[strides == s0][:, 0].max()) / s0 + 0.5))
    h0 = int((strides == s0).sum()) // w0
    for g in torch.nonzero(~has).flatten().tolist():
        col = min(max(int(float(cu[0, g]) // s0), 0), w0 - 1)
        row = min(max(int(float(cv[0, g]) // s0), 0), h0 - 1)
        k = row * w0 + col
        if out[k] < 0:
            out[k] = g
    return out


def detection_loss(
    reg: torch.Tensor,
    cls: torch.Tensor,
    targets: list[tuple[torch.Tensor, torch.Tensor]],
    points: torch.Tensor,
    strides: torch.Tensor,
    box_weight: float = 2.0,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Loss of a batch: (B, N, 4) raw distances, (B, N, nc) logits, per image (G,) classes and (G, 4) xyxy boxes."""
    boxes = decode(reg, points, strides)
    cls_target = torch.zeros_like(cls)
    pred_pos, gt_pos = [], []
    pos_index = []
    for b, (classes, gt) in enumerate(targets):
        a = assign(gt, points, strides)
        k = torch.nonzero(a >= 0).flatten()
        if len(k):
            pred_pos.append(boxes[b, k])
            gt_pos.append(gt[a[k]])
            pos_index.append((b, k, classes[a[k]]))
    n_pos = max(sum(len(k) for _, k, _ in pos_index), 1)
    if pred_pos:
        pb, gb = torch.cat(pred_pos), torch.cat(gt_pos)
        iou, giou = box_iou_pairs(pb, gb)
        box_loss = (1.0 - giou).sum() / n_pos
        q = iou.detach().clamp(min=0.0)
        i = 0
        for b, k, c in pos_index:
            cls_target[b, k, c] = q[i : i + len(k)]
            i += len(k)
    else:
        box_loss = reg.sum() * 0.0
    p = cls.sigmoid()
    qfl = F.binary_cross_entropy_with_logits(cls, cls_target, reduction="none") * (p - cls_target).abs().pow(2)
    cls_loss = qfl.sum() / n_pos
    total = cls_loss + box_weight * box_loss
    return total, {"cls": float(cls_loss.detach()), "box": float(box_loss.detach()), "pos": float(n_pos)}

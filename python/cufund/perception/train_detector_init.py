"""Starting a training run from a model ``cufund train-detector`` exported (``--init MODEL.onnx``).

The export folds each batch normalisation into the convolution before it (``do_constant_folding``): the ONNX file
holds, per convolution, ``W_f = W g / sqrt(var + eps)`` and ``b_f = beta - mean g / sqrt(var + eps)``, and the
batch normalisation's own four vectors are gone. They cannot be recovered, but any choice that keeps
``conv(x; W_f) + b_f`` is the same network. :func:`load_exported_weights` puts ``W_f`` in the convolution and
chooses the batch normalisation from data: ``running_mean = mu``, ``running_var = s^2``, ``weight = sqrt(s^2 +
eps)``, ``bias = mu + b_f``, with ``mu`` and ``s^2`` the per-channel mean and variance of ``conv(x; W_f)`` over
calibration images. In eval mode that is exactly ``conv(x; W_f) + b_f`` again (the model exports to the same
outputs); in train mode, where batch normalisation uses the batch's own statistics, it is that up to how far a
batch's statistics are from the calibration images', so fine-tuning starts from the exported network rather than
from one whose layers are all rescaled.

The file is read as data only: an ONNX whose tensors live in external files is refused (they would be read from
wherever the file points), as is one whose graph does not have this model's convolutions, in this order, with these
shapes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["load_exported_weights"]


def _conv_tensors(path: Path) -> list[tuple[str, np.ndarray, np.ndarray | None]]:
    """Per Conv node of the graph, in the graph's order: (node name, weight, bias or None)."""
    import onnx
    from onnx import numpy_helper

    try:
        proto = onnx.load(str(path), load_external_data=False)
    except Exception as e:  # protobuf's decode errors have no common base
        raise ValueError(f"init weights {str(path)!r} are not an ONNX model: {str(e)[:200]}") from None
    inits = {}
    for t in proto.graph.initializer:
        if t.data_location == onnx.TensorProto.EXTERNAL:
            raise ValueError(f"init weights {str(path)!r}: tensor {t.name!r} is stored in an external file (refused)")
        inits[t.name] = t
    for node in proto.graph.node:  # the exporter stores equal tensors once and aliases the others by Identity
        if node.op_type == "Identity" and len(node.input) == 1 and node.input[0] in inits:
            inits[node.output[0]] = inits[node.input[0]]
    convs = []
    for node in proto.graph.node:
        if node.op_type != "Conv":
            continue
        stored = [len(node.input) > i and node.input[i] in inits for i in (1, 2)]
        if not stored[0] or (len(node.input) > 2 and node.input[2] and not stored[1]):
            raise ValueError(f"init weights {str(path)!r}: Conv {node.name!r} has no stored weight or bias")
        w = numpy_helper.to_array(inits[node.input[1]])
        b = numpy_helper.to_array(inits[node.input[2]]) if stored[1] else None
        convs.append((node.name, w, b))
    return convs


def load_exported_weights(model: Any, path: str | Path, images: np.ndarray) -> None:
    """Sets ``model`` (a :class:`~cufund.perception.train_detector_model.Detector`) to the network exported in
    ``path``; ``images`` (n, H, W, 3) uint8 RGB letterboxed to the model's input are the calibration images of the
    batch normalisations (module doc). Raises ValueError naming the file when it does not fit the model."""
    import torch
    from torch import nn

    path = Path(path)
    convs = _conv_tensors(path)
    pairs: list[tuple[nn.Conv2d, nn.BatchNorm2d | None]] = []
    modules = list(model.modules())
    for i, m in enumerate(modules):
        if isinstance(m, nn.Conv2d):
            bn = modules[i + 1] if i + 1 < len(modules) and isinstance(modules[i + 1], nn.BatchNorm2d) else None
            pairs.append((m, bn))
    if len(convs) != len(pairs):
        raise ValueError(
            f"init weights {str(path)!r} do not fit this model: {len(convs)} convolutions, the model has {len(pairs)}"
            " (same width, depth and classes?)"
        )
    offsets: list[torch.Tensor] = []
    for k, ((name, w, b), (conv, bn)) in enumerate(zip(convs, pairs, strict=True)):
        if tuple(w.shape) != tuple(conv.weight.shape):
            raise ValueError(
                f"init weights {str(path)!r} do not fit this model: convolution {k} ({name}) is "
                f"{list(w.shape)}, the model's {list(conv.weight.shape)} (same width, depth and classes?)"
            )
        if not np.all(np.isfinite(w)) or (b is not None and not np.all(np.isfinite(b))):
            raise ValueError(f"init weights {str(path)!r}: convolution {k} ({name}) holds non-finite numbers")
        bias = np.zeros(w.shape[0], np.float32) if b is None else b.astype(np.float32)
        if bias.shape != (w.shape[0],):
            raise ValueError(f"init weights {str(path)!r}: convolution {k} ({name}) has a bias of shape {bias.shape}")
        if (bn is None) != (conv.bias is not None):
            raise ValueError(f"init weights {str(path)!r} do not fit this model at convolution {k} ({name})")
        with torch.no_grad():
            conv.weight.copy_(torch.from_numpy(w.astype(np.float32)))
            if bn is None:
                assert conv.bias is not None
                conv.bias.copy_(torch.from_numpy(bias))
            else:  # the identity plus b_f until calibrated: the eval network is the exported one
                assert bn.running_mean is not None and bn.running_var is not None  # track_running_stats
                bn.running_mean.zero_()
                bn.running_var.fill_(1.0 - bn.eps)
                bn.weight.fill_(1.0)
                bn.bias.copy_(torch.from_numpy(bias))
        offsets.append(torch.from_numpy(bias))
    # per-channel statistics of each folded convolution's output over the calibration images
    stats: dict[int, torch.Tensor] = {}  # per folded convolution: sums of y and y^2 per channel, and the count
    hooks = []
    for k, (conv, bn) in enumerate(pairs):
        if bn is None:
            continue

        def hook(_m: Any, _i: Any, out: torch.Tensor, k: int = k) -> None:
            y = out.detach().double()
            row = torch.cat([y.sum((0, 2, 3)), (y * y).sum((0, 2, 3)), torch.tensor([float(y[:, 0].numel())])])
            stats[k] = row if k not in stats else stats[k] + row

        hooks.append(conv.register_forward_hook(hook))
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            for s in range(0, len(images), 16):
                x = torch.from_numpy(np.ascontiguousarray(images[s : s + 16].transpose(0, 3, 1, 2))).float() / 255.0
                model(x)
    finally:
        for h in hooks:
            h.remove()
    with torch.no_grad():
        for k, (_conv, bn) in enumerate(pairs):
            if bn is None:
                continue
            c = bn.num_features
            m1, m2 = stats[k][:c] / stats[k][-1], stats[k][c : 2 * c] / stats[k][-1]
            var = torch.clamp(m2 - m1 * m1, min=1e-6)
            assert bn.running_mean is not None and bn.running_var is not None
            bn.running_mean.copy_(m1.float())
            bn.running_var.copy_(var.float())
            bn.weight.copy_(torch.sqrt(var + bn.eps).float())
            bn.bias.copy_((m1 + offsets[k].double()).float())
    model.train(was_training)

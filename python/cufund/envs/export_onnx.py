"""A trained MLP policy as an ONNX graph, and the manifest a deployment checks it against.

The graph is built node by node with ``onnx.helper`` (no converter, no torch): input ``obs`` [N, obs_dim] float32,

    z = clip((obs - mean) / (sqrt(var) + eps), -c, c)        the observation standardisation the policy trained with
    h = tanh(z W_0 + b_0) ... tanh(h W_{L-2} + b_{L-2})      hidden layers
    action = clip(h W_{L-1} + b_{L-1}, low, high)            the deterministic (mean) action, clipped to the space

output ``action`` [N, act_dim] float32. The manifest (:class:`PolicyManifest`) is written beside it as
``policy.yaml`` and also into the model's ``metadata_props``, so the ``.onnx`` file alone says what it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cufund.control.policy_manifest import PolicyManifest

__all__ = ["PolicyManifest", "export_mlp", "read_manifest"]

OPSET = 17


def export_mlp(
    path: str | Path,
    layers: Sequence[tuple[np.ndarray, np.ndarray]],
    manifest: PolicyManifest,
    obs_mean: np.ndarray | None = None,
    obs_var: np.ndarray | None = None,
    obs_eps: float = 1e-8,
    obs_clip: float = 5.0,
    act_low: float = -1.0,
    act_high: float = 1.0,
) -> Path:
    """Writes the policy MLP ``layers`` [(W (in, out), b (out,)), ...] (tanh between them) with the observation
    standardisation (``obs_mean``/``obs_var``; None: none) to ``path`` and ``policy.yaml`` beside it. Returns the
    path of the ONNX file."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    if not layers:
        raise ValueError("layers must hold at least one (W, b) pair")
    Ws = [np.asarray(W, dtype=np.float32) for W, _ in layers]
    bs = [np.asarray(b, dtype=np.float32).reshape(-1) for _, b in layers]
    for i, (W, b) in enumerate(zip(Ws, bs, strict=True)):
        if W.ndim != 2 or b.shape != (W.shape[1],):
            raise ValueError(f"layer {i}: W must be (in, out) and b (out,), got {W.shape} and {b.shape}")
        if i and W.shape[0] != Ws[i - 1].shape[1]:
            raise ValueError(f"layer {i}: takes {W.shape[0]} inputs but layer {i - 1} gives {Ws[i - 1].shape[1]}")
    obs_dim, act_dim = Ws[0].shape[0], Ws[-1].shape[1]
    if (obs_dim, act_dim) != (manifest.obs_dim, manifest.act_dim):
        raise ValueError(
            f"the network maps {obs_dim} -> {act_dim} but the manifest says obs_dim={manifest.obs_dim}, "
            f"act_dim={manifest.act_dim}"
        )
    inits = []
    nodes = []
    x = "obs"
    if obs_mean is not None:
        mean = np.asarray(obs_mean, dtype=np.float32).reshape(obs_dim)
        var = np.asarray(obs_var, dtype=np.float32).reshape(obs_dim)
        # the same float32 operations as skrl's RunningStandardScaler: (x - mean) / (sqrt(var) + eps)
        denom = (np.sqrt(var) + np.float32(obs_eps)).astype(np.float32)
        inits += [
            numpy_helper.from_array(mean, "obs_mean"),
            numpy_helper.from_array(denom, "obs_denom"),
            numpy_helper.from_array(np.array(-obs_clip, np.float32), "obs_clip_lo"),
            numpy_helper.from_array(np.array(obs_clip, np.float32), "obs_clip_hi"),
        ]
        nodes += [
            helper.make_node("Sub", [x, "obs_mean"], ["obs_centred"]),
            helper.make_node("Div", ["obs_centred", "obs_denom"], ["obs_scaled"]),
            helper.make_node("Clip", ["obs_scaled", "obs_clip_lo", "obs_clip_hi"], ["obs_std"]),
        ]
        x = "obs_std"
    for i, (W, b) in enumerate(zip(Ws, bs, strict=True)):
        inits += [numpy_helper.from_array(W, f"W{i}"), numpy_helper.from_array(b, f"b{i}")]
        nodes.append(helper.make_node("Gemm", [x, f"W{i}", f"b{i}"], [f"z{i}"]))
        x = f"z{i}"
        if i < len(Ws) - 1:
            nodes.append(helper.make_node("Tanh", [x], [f"h{i}"]))
            x = f"h{i}"
    inits += [
        numpy_helper.from_array(np.array(act_low, np.float32), "act_lo"),
        numpy_helper.from_array(np.array(act_high, np.float32), "act_hi"),
    ]
    nodes.append(helper.make_node("Clip", [x, "act_lo", "act_hi"], ["action"]))
    graph = helper.make_graph(
        nodes,
        "cufund_policy",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["N", obs_dim])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["N", act_dim])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="cufund")
    model.ir_version = 8  # readable by onnxruntime >= 1.14
    for k, v in manifest.to_dict().items():
        model.metadata_props.add(key=k, value=yaml.safe_dump(v, default_flow_style=True).strip())
    onnx.checker.check_model(model)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(model, str(path))
    manifest.write(path.with_name("policy.yaml") if path.name == "policy.onnx" else path.with_suffix(".yaml"))
    return path


def read_manifest(onnx_path: str | Path) -> dict[str, Any]:
    """The manifest stored in an exported model's ``metadata_props`` (as a mapping)."""
    import onnx

    model = onnx.load(str(onnx_path), load_external_data=False)
    return {p.key: yaml.safe_load(p.value) for p in model.metadata_props}

"""The observation a learned policy sees: defined once, here, for the environments (``cufund.envs``, whose C++ code
builds the same numbers bit for bit) and for the ``policy`` controller (which builds it from the estimate and the
IMU).

Layout of one observation (float32, SI units, frames as named)::

    [ target block 0 | target block 1 | ... | target block K-1 | v_W (3) | R_WB (9, row-major) | w_B (3) | a_prev (4) ]

- target block k, ``target_dim`` = 3: ``p_k - p_W``, the k-th next target's position relative to the vehicle in
  the world frame [m] (hover: the hover point; waypoints: the next waypoints in order, or, along a timed reference,
  the reference extrapolated k * lookahead_s ahead: :func:`lookahead_targets`);
- target block k, ``target_dim`` = 6: the same 3 followed by the gate's normal ``x_G`` in the world frame (the
  direction it is to be flown through; gates);
- ``v_W`` the velocity [m/s], world ENU;
- ``R_WB`` the attitude as the rotation matrix body FLU -> world, row-major, from q_WB [w, x, y, z] normalised in
  the formula (``s = 2 / |q|^2``), so a policy sees no quaternion sign flip;
- ``w_B`` the body rate [rad/s], FLU (the gyro's reading when the IMU noise option is on);
- ``a_prev`` the action applied in the previous step, in [-1, 1]^4 (zeros after a reset).

Every number is computed in double precision in the order written in :func:`build_observation` and rounded to
float32 once; the C++ environments (``cpp/envs/env_batch.cpp``) follow the same order without FMA contraction, so
the two agree bit for bit (tests/envs/test_vector_envs.py).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ACTION_SIZE",
    "BASE_SIZE",
    "LAYOUT_VERSION",
    "build_observation",
    "lookahead_targets",
    "observation_size",
    "rotation_rows",
    "slices",
]

ACTION_SIZE = 4
"""Actions are 4 numbers in [-1, 1] in every action mode."""
BASE_SIZE = 3 + 9 + 3 + ACTION_SIZE
"""The entries after the target blocks: v_W, R_WB, w_B, a_prev."""
LAYOUT_VERSION = 1
"""Version of this layout: change it with any change above, so that an exported policy trained on another layout is
refused by the ``policy`` controller (its ``policy.yaml`` names the version it saw)."""


def observation_size(n_targets: int, target_dim: int = 3) -> int:
    """Length of one observation with ``n_targets`` target blocks of ``target_dim`` (3 or 6) numbers."""
    if target_dim not in (3, 6):
        raise ValueError(f"target_dim must be 3 (position) or 6 (position and gate normal), got {target_dim!r}")
    if isinstance(n_targets, bool) or not isinstance(n_targets, int) or n_targets < 1:
        raise ValueError(f"n_targets must be an integer >= 1, got {n_targets!r}")
    return n_targets * target_dim + BASE_SIZE


def slices(n_targets: int, target_dim: int = 3) -> dict[str, slice]:
    """Where each named part sits in an observation: ``targets``, ``v_W``, ``R_WB``, ``w_B``, ``a_prev``."""
    t = n_targets * target_dim
    observation_size(n_targets, target_dim)
    return {
        "targets": slice(0, t),
        "v_W": slice(t, t + 3),
        "R_WB": slice(t + 3, t + 12),
        "w_B": slice(t + 12, t + 15),
        "a_prev": slice(t + 15, t + 19),
    }


def rotation_rows(q_WB: np.ndarray) -> np.ndarray:
    """R_WB (N, 9) row-major, float64, of quaternions q_WB (N, 4) [w, x, y, z], normalised in the formula."""
    q = np.asarray(q_WB, dtype=np.float64)
    qw, qx, qy, qz = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    s = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    R = np.empty((q.shape[0], 9))
    R[:, 0] = 1.0 - s * (qy * qy + qz * qz)
    R[:, 1] = s * (qx * qy - qw * qz)
    R[:, 2] = s * (qx * qz + qw * qy)
    R[:, 3] = s * (qx * qy + qw * qz)
    R[:, 4] = 1.0 - s * (qx * qx + qz * qz)
    R[:, 5] = s * (qy * qz - qw * qx)
    R[:, 6] = s * (qx * qz - qw * qy)
    R[:, 7] = s * (qy * qz + qw * qx)
    R[:, 8] = 1.0 - s * (qx * qx + qy * qy)
    return R


def build_observation(
    targets_W: np.ndarray,
    p_W: np.ndarray,
    v_W: np.ndarray,
    q_WB: np.ndarray,
    w_B: np.ndarray,
    a_prev: np.ndarray,
    gate_normals_W: np.ndarray | None = None,
) -> np.ndarray:
    """Observations (N, observation_size(K, D)) float32 of N vehicles.

    ``targets_W`` (N, K, 3) the next K targets' positions [m], world; ``p_W`` (N, 3), ``v_W`` (N, 3), ``q_WB``
    (N, 4) [w, x, y, z], ``w_B`` (N, 3), ``a_prev`` (N, 4); ``gate_normals_W`` (N, K, 3) makes target blocks of 6
    (gates). A single vehicle may pass 1-D arrays (and (K, 3) targets); it gets a 1-D observation.
    """
    single = np.ndim(p_W) == 1
    p = np.atleast_2d(np.asarray(p_W, dtype=np.float64))
    n = p.shape[0]
    tg = np.asarray(targets_W, dtype=np.float64).reshape(n, -1, 3)
    k = tg.shape[1]
    dim = 3 if gate_normals_W is None else 6
    rel = tg - p[:, None, :]
    if gate_normals_W is None:
        blocks = rel
    else:
        blocks = np.concatenate([rel, np.asarray(gate_normals_W, dtype=np.float64).reshape(n, k, 3)], axis=2)
    out = np.empty((n, observation_size(k, dim)), dtype=np.float32)
    sl = slices(k, dim)
    out[:, sl["targets"]] = blocks.reshape(n, k * dim)
    out[:, sl["v_W"]] = np.atleast_2d(v_W)
    out[:, sl["R_WB"]] = rotation_rows(np.atleast_2d(q_WB))
    out[:, sl["w_B"]] = np.atleast_2d(w_B)
    out[:, sl["a_prev"]] = np.atleast_2d(a_prev)
    return out[0] if single else out


def lookahead_targets(
    p_W: np.ndarray, v_W: np.ndarray, a_W: np.ndarray, n_targets: int, lookahead_s: float
) -> np.ndarray:
    """The target blocks' points (n_targets, 3) of a timed reference at p_W, v_W, a_W (3,) [m, m/s, m/s^2]: block k
    is the reference extrapolated tau = k * lookahead_s [s] ahead, ``p + v tau + 0.5 a tau tau`` (in this order, as
    the environments' C++ computes it)."""
    p = np.asarray(p_W, dtype=np.float64).reshape(3)
    v = np.asarray(v_W, dtype=np.float64).reshape(3)
    a = np.asarray(a_W, dtype=np.float64).reshape(3)
    out = np.empty((n_targets, 3))
    for k in range(n_targets):
        tau = k * lookahead_s
        out[k] = p + v * tau + 0.5 * a * tau * tau
    return out

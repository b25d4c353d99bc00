"""What an open-loop odometry rerun on a recorded log reports, for any estimator (the LIO's
:func:`~cufund.estimation.offline.run_on_log`, the VIO's :func:`~cufund.estimation.vio_offline.run_vio_on_log`): its
outputs against the log's truth interpolated at each output's stamp, and the files written for ``evo``."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from .evaluation import aligned_ate, flight_window, odometry_errors, write_tum

__all__ = ["OpenLoopTrack", "against_truth", "write_open_loop"]


@dataclass(frozen=True)
class OpenLoopTrack:
    """The estimate's outputs inside the truth's time span, and the truth at their stamps."""

    t: np.ndarray
    p: np.ndarray
    q: np.ndarray
    p_true: np.ndarray
    q_true: np.ndarray


def against_truth(
    outputs: Sequence[Any], truth_t: Sequence[float], truth_p: Sequence[Any], truth_q: Sequence[Any]
) -> tuple[OpenLoopTrack, dict[str, Any]]:
    """The outputs (each with ``t``, ``p_W``, ``q_WB``) against the truth (positions linearly, attitudes by slerp at
    each output's stamp): the track and the figures (unaligned errors, and evo's aligned APE from take-off to
    touchdown)."""
    t = np.array([o.t for o in outputs])
    p = np.array([o.p_W for o in outputs])
    q = np.array([o.q_WB for o in outputs])
    tt, order = np.unique(np.array(truth_t), return_index=True)
    tp, tq = np.array(truth_p)[order], np.array(truth_q)[order]
    inside = (t >= tt[0]) & (t <= tt[-1])
    t, p, q = t[inside], p[inside], q[inside]
    p_true = np.column_stack([np.interp(t, tt, tp[:, i]) for i in range(3)])
    q_true = Slerp(tt, Rotation.from_quat(tq[:, [1, 2, 3, 0]]))(t).as_quat()[:, [3, 0, 1, 2]]
    figures: dict[str, Any] = odometry_errors(p, q, p_true, q_true)
    flying = flight_window(p_true[:, 2])
    figures["odometry_ate_aligned_m"] = (
        aligned_ate(p[flying], p_true[flying]) if flying.stop - flying.start >= 3 else None
    )
    return OpenLoopTrack(t, p, q, p_true, q_true), figures


def write_open_loop(out_dir: str | Path, figures: dict[str, Any], track: OpenLoopTrack, label: str) -> None:
    """``odometry.json`` (the figures), ``estimate.tum`` and ``truth.tum`` (for ``evo``) and ``odometry.png`` (in the
    style of the paper's Fig. 8; ``label`` names the estimate) in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "odometry.json").write_text(json.dumps(figures, indent=2) + "\n")
    write_tum(out / "estimate.tum", track.t, track.p, track.q)
    write_tum(out / "truth.tum", track.t, track.p_true, track.q_true)
    _plot(out / "odometry.png", track, label)


def _plot(path: Path, track: OpenLoopTrack, label: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, p, p_true = track.t, track.p, track.p_true
    fig, axes = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    for i, name in enumerate("xyz"):
        axes[i].plot(t, p_true[:, i], "k-", lw=1.2, label="truth")
        axes[i].plot(t, p[:, i], "r--", lw=1.0, label=label)
        axes[i].set_ylabel(f"{name} [m]")
    axes[0].legend(loc="best")
    axes[3].plot(t, np.linalg.norm(p - p_true, axis=1) * 1e3, "b-", lw=1.0)
    axes[3].set_ylabel("|error| [mm]")
    axes[3].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

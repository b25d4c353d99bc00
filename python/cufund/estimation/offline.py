"""The LIO run open loop on a recorded log (``run.mcap``): the figures against the log's ground truth, a plot in
the style of the paper's Fig. 8, and TUM files of the estimate and the truth for ``evo``.

The log's first true state gives the estimator what a pad gives a real vehicle: the world frame's origin and yaw
(roll, pitch and the biases it estimates). Errors are |p_true - p_est| at each estimator output with the truth
interpolated at the output's stamp, unaligned and as evo's aligned APE from take-off to touchdown.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from cufund.core.messages import Topics
from cufund.geometry import yaw_of

from .evaluation import aligned_ate, flight_window, odometry_errors, write_tum
from .params import LioParams

__all__ = ["run_on_log"]


def run_on_log(
    path: str | Path,
    params: LioParams | None = None,
    out_dir: str | Path | None = None,
    imu_topic: str = Topics.IMU,
    lidar_topic: str = Topics.POINT_CLOUD,
    truth_topic: str = Topics.TRUTH_ODOMETRY,
) -> dict[str, Any]:
    """Runs :class:`LioEstimator` on the IMU and LiDAR messages of the log at ``path`` in log-time order and
    returns the figures (``odometry_min_m``, ``odometry_rmse_m``, ``odometry_max_m``, ``odometry_rot_rmse_deg``,
    ``lio_ms_per_scan_median``, ``lio_ms_per_scan_p99``, counts). With ``out_dir``: writes ``odometry.json``,
    ``odometry.png``, ``estimate.tum`` and ``truth.tum`` there."""
    import dataclasses

    from cufund.logs.mcap_reader import read_mcap
    from cufund.logs.rosbag2_reader import is_rosbag2, read_rosbag2

    from .lio_estimator import LioEstimator

    params = params or LioParams()
    truth_t, truth_p, truth_q = [], [], []
    est = None
    outputs = []
    pending_clouds: list[Any] = []
    read = read_rosbag2 if is_rosbag2(path) else read_mcap  # a ROS 2 bag folder or a run.mcap
    for rec in read(path, topics=[imu_topic, lidar_topic, truth_topic]):
        msg = rec.message
        if rec.topic == truth_topic:
            truth_t.append(msg.t)
            truth_p.append(np.asarray(msg.p_W, float))
            truth_q.append(np.asarray(msg.q_WB, float))
            if est is None:  # the pad: the world frame's origin and yaw, nothing else
                est = LioEstimator(dataclasses.replace(params, p_WB0=tuple(truth_p[0]), pad_yaw=yaw_of(truth_q[0])))
        elif rec.topic == lidar_topic:
            pending_clouds.append(msg)
        elif est is not None:
            outputs += est.feed(pending_clouds, [msg])
            pending_clouds = []
    if est is None or not outputs:
        raise ValueError(
            f"{path}: no estimate: the log needs {truth_topic} (the pad pose), {imu_topic} for at least "
            f"the initialisation time and {lidar_topic}"
        )
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
    ms = np.array([d.time_ms for d in est.diagnostics if not d.skipped])
    figures["lio_ms_per_scan_median"] = float(np.median(ms)) if len(ms) else None
    figures["lio_ms_per_scan_p99"] = float(np.percentile(ms, 99)) if len(ms) else None
    figures["odometry_samples"] = int(len(t))
    figures["lio_scans"] = int(len(ms))
    figures["lio_scans_skipped"] = int(est.core.skipped_scans)
    figures["lio_scans_degenerate"] = int(sum(1 for d in est.diagnostics if d.degenerate_directions))
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / "odometry.json").write_text(json.dumps(figures, indent=2) + "\n")
        write_tum(out / "estimate.tum", t, p, q)
        write_tum(out / "truth.tum", t, p_true, q_true)
        _plot(out / "odometry.png", t, p, p_true)
    return figures


def _plot(path: Path, t: np.ndarray, p: np.ndarray, p_true: np.ndarray) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    for i, name in enumerate("xyz"):
        axes[i].plot(t, p_true[:, i], "k-", lw=1.2, label="truth")
        axes[i].plot(t, p[:, i], "r--", lw=1.0, label="LIO estimate")
        axes[i].set_ylabel(f"{name} [m]")
    axes[0].legend(loc="best")
    axes[3].plot(t, np.linalg.norm(p - p_true, axis=1) * 1e3, "b-", lw=1.0)
    axes[3].set_ylabel("|error| [mm]")
    axes[3].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

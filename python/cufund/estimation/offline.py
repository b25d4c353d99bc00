"""The LIO run open loop on a recorded log (``run.mcap``): the figures against the log's ground truth, a plot in
the style of the paper's Fig. 8, and TUM files of the estimate and the truth for ``evo``.

The log's first true state gives the estimator what a pad gives a real vehicle: the world frame's origin and yaw
(roll, pitch and the biases it estimates). Errors are |p_true - p_est| at each estimator output with the truth
interpolated at the output's stamp, unaligned and as evo's aligned APE from take-off to touchdown.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.messages import Topics
from cufund.geometry import yaw_of

from .open_loop import against_truth, write_open_loop
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
    track, figures = against_truth(outputs, truth_t, truth_p, truth_q)
    ms = np.array([d.time_ms for d in est.diagnostics if not d.skipped])
    figures["lio_ms_per_scan_median"] = float(np.median(ms)) if len(ms) else None
    figures["lio_ms_per_scan_p99"] = float(np.percentile(ms, 99)) if len(ms) else None
    figures["odometry_samples"] = int(len(track.t))
    figures["lio_scans"] = int(len(ms))
    figures["lio_scans_skipped"] = int(est.core.skipped_scans)
    figures["lio_scans_degenerate"] = int(sum(1 for d in est.diagnostics if d.degenerate_directions))
    if out_dir is not None:
        write_open_loop(out_dir, figures, track, "LIO estimate")
    return figures

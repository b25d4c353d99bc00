"""The VIO run open loop on a recorded log (``run.mcap`` with both cameras' images and the IMU): the figures against
the log's ground truth and TUM files for ``evo``, as :func:`cufund.estimation.offline.run_on_log` gives the LIO's.

The log's first true state gives the estimator what a pad gives a real vehicle: the world frame's origin and yaw.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.messages import Topics
from cufund.geometry import yaw_of

from .open_loop import against_truth, write_open_loop
from .vio_params import VioParams

__all__ = ["run_vio_on_log"]


def run_vio_on_log(
    path: str | Path,
    params: VioParams,
    out_dir: str | Path | None = None,
    imu_topic: str = str(Topics.IMU),
    camera_topics: tuple[str, ...] = ("/sensors/cam0/image", "/sensors/cam1/image"),
    truth_topic: str = str(Topics.TRUTH_ODOMETRY),
) -> dict[str, Any]:
    """Runs :class:`VioEstimator` on the log's IMU samples and stereo images in log-time order; returns the
    figures (``odometry_*``, ``vio_ms_per_frame_median``, ``vio_frames``, ``vio_unhealthy_frames``,
    ``vio_time_offset_s``). ``camera_topics``: left and right, or the left alone (``cameras: mono``). With
    ``out_dir``: ``odometry.json``, ``estimate.tum`` and ``truth.tum`` there."""
    from cufund.logs.mcap_reader import read_mcap

    from .vio_estimator import VioEstimator

    left_topic, right_topic = camera_topics[0], (camera_topics[1] if len(camera_topics) > 1 else None)
    truth_t, truth_p, truth_q = [], [], []
    est: VioEstimator | None = None
    outputs: list[Any] = []
    left: list[Any] = []
    right: list[Any] = []
    topics = [imu_topic, *camera_topics, truth_topic]
    for rec in read_mcap(path, topics=topics):
        msg = rec.message
        if rec.topic == truth_topic:
            truth_t.append(msg.t)
            truth_p.append(np.asarray(msg.p_W, float))
            truth_q.append(np.asarray(msg.q_WB, float))
            if est is None:
                est = VioEstimator(
                    dataclasses.replace(params, p_WB0=tuple(truth_p[0]), pad_yaw=yaw_of(truth_q[0])),
                    imu_topic,
                    left_topic,
                    right_topic,
                )
        elif rec.topic == left_topic:
            left.append(msg)
        elif rec.topic == right_topic:
            right.append(msg)
        elif est is not None:
            outputs += est.feed(left, right, [msg])
            left, right = [], []
    if est is None or not outputs:
        raise ValueError(
            f"{path}: no estimate: the log needs {truth_topic} (the pad pose), {imu_topic} for at least the "
            f"initialisation time and the images of {' and '.join(camera_topics)}"
        )
    track, figures = against_truth(outputs, truth_t, truth_p, truth_q)
    diag = est.core.diagnostics
    ms = np.array([d.time_ms for d in diag])
    figures["vio_ms_per_frame_median"] = float(np.median(ms)) if len(ms) else None
    figures["vio_cpu_ms_per_frame_median"] = float(np.median([d.cpu_ms for d in diag])) if diag else None
    figures["odometry_samples"] = int(len(track.t))
    figures["vio_frames"] = len(diag)
    figures["vio_keyframes"] = int(sum(d.keyframe for d in diag))
    figures["vio_unhealthy_frames"] = int(sum(not d.healthy for d in diag))
    figures["vio_time_offset_s"] = est.core.time_offset_s
    figures["vio_frames_skipped"] = est.core.skipped_frames
    figures["vio_unpaired_images"] = est.unpaired_images
    if out_dir is not None:
        write_open_loop(out_dir, figures, track, "VIO estimate")
    return figures

"""Metrics of a tunnel mission run (paper Table 1 and the issue's success criterion), measured after the run
against ground truth (the true states and the true frames: metrics only, never flight inputs)."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from cufund.core.messages import Topics

from .tunnel_geometry import frame_boxes, passages

__all__ = ["component_split", "tracking_errors", "true_frames", "tunnel_metrics"]

_GROUPS = (
    ("lio", ("lio", "estimator")),
    ("mapping", ("esdf", "mapper")),
    ("detection", ("detector", "tunnel")),
    ("planning", ("mission", "follower", "planner")),
    ("control", ("control", "pid", "geometric", "mixer", "attitude", "rate", "position")),
    ("physics", ("physics",)),
    ("sensors", ("lidar", "imu", "sensor", "mid360", "icm")),
)


def true_frames(course: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Centres (K, 3), normals (K, 3), opening sizes (K, 2) and bar thickness of the course's true frames."""
    f = course.frames
    return (
        np.array([x.centre_W for x in f], dtype=float),
        np.array([x.axis_W for x in f], dtype=float),
        np.array([[x.width, x.height] for x in f], dtype=float),
        0.05,
    )


def tracking_errors(result: Any, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and |p_true - p_setpoint| [m] at every trajectory setpoint published in [t0, t1] (the true position
    interpolated at the setpoint's stamp)."""
    sp = result.topics.get(str(Topics.TRAJECTORY_SETPOINT), {})
    if not sp:
        return np.zeros(0), np.zeros(0)
    ts = np.asarray(sp["t"], dtype=float)
    m = (ts >= t0) & (ts <= t1) & (ts >= result.states["t"][0]) & (ts <= result.states["t"][-1])
    ts, p_sp = ts[m], np.asarray(sp["p_W"], dtype=float)[m]
    t, p = result.states["t"], result.states["p_W"]
    p_true = np.stack([np.interp(ts, t, p[:, i]) for i in range(3)], axis=1)
    return ts, np.linalg.norm(p_true - p_sp, axis=1)


def component_split(component_seconds: dict[str, float]) -> dict[str, float]:
    """Wall time [s] per part of the stack (LIO, mapping, detection, planning, control, physics, sensors, other)."""
    out: dict[str, float] = {g: 0.0 for g, _ in _GROUPS}
    out["other"] = 0.0
    for name, sec in component_seconds.items():
        low = name.lower()
        for g, keys in _GROUPS:
            if any(k in low for k in keys):
                out[g] += sec
                break
        else:
            out["other"] += sec
    return {k: round(v, 4) for k, v in out.items()}


def tunnel_metrics(result: Any, mission: Any, course: Any) -> dict[str, Any]:
    """``status`` ('completed', 'aborted' or the run's own: collision, timeout ...), ``reason``, ``success`` (every
    frame passed in order inside its opening, no contact, landed beyond the last frame), tracking errors over the
    flight (take-off to touchdown), ``min_clearance_m`` (the true centre's distance to the nearest true bar or
    leg), ``mission_time_s`` (take-off to touchdown), ``detection_centre_error_m`` (largest error of the flown
    detections), and the time split per part of the stack."""
    sim_status = getattr(result.status, "value", str(result.status))
    t, p = result.states["t"], result.states["p_W"]
    out: dict[str, Any] = {
        "sim_status": sim_status,
        "mission_state": mission.state,
        "reason": mission.reason,
        "frames_passed_estimated": int(mission.progress),
    }
    if sim_status != "completed":
        out["status"] = sim_status
    else:
        out["status"] = (
            "completed" if mission.state == "done" else "aborted" if mission.state == "aborted" else mission.state
        )
    out["transitions"] = [[round(a, 3), b, c] for a, b, c in mission.transitions]
    t_takeoff = next((a for a, b, _ in mission.transitions if b == "takeoff"), None)
    t_end = mission.t_end
    if t_takeoff is not None:
        t1 = t_end if t_end is not None else float(t[-1])
        # touchdown: the landing's reference goes on below the ground, the vehicle stops on it
        up = np.flatnonzero((t >= t_takeoff) & (p[:, 2] > p[0, 2] + 0.02))
        if len(up) and mission.state in ("done", "aborted"):
            t1 = min(t1, float(t[up[-1]]))
        _, err = tracking_errors(result, t_takeoff, t1)
        if err.size:
            out.update(
                {
                    "tracking_min_m": float(err.min()),
                    "tracking_rmse_m": float(np.sqrt(np.mean(err**2))),
                    "tracking_max_m": float(err.max()),
                    "tracking_samples": int(err.size),
                }
            )
        out["mission_time_s"] = float(t1 - t_takeoff) if mission.state == "done" else None
    else:
        out["mission_time_s"] = None
    for key in ("tracking_min_m", "tracking_rmse_m", "tracking_max_m"):
        out.setdefault(key, None)
    passed_all = False
    if course is not None:
        c, n, s, bar = true_frames(course)
        clear = frame_boxes(c, n, s, bar).distance(p)
        out["min_clearance_m"] = float(clear.min()) if clear.size else None
        idx = passages(p, c, n, s)
        out["frames_passed"] = int(sum(i is not None for i in idx))
        order = [i for i in idx if i is not None]
        passed_all = len(order) == len(idx) and all(a < b for a, b in itertools.pairwise(order))
        d = mission.used
        if d is not None and d.centres.shape[0] == c.shape[0]:
            e = np.linalg.norm(d.centres - c, axis=1)
            out["detection_centre_error_m"] = float(e.max())
            out["detection_centre_errors_m"] = [round(float(x), 4) for x in e]
            ang = np.degrees(
                np.arccos(np.clip(np.sum(d.normals * n, axis=1) / np.linalg.norm(d.normals, axis=1), -1, 1))
            )
            out["detection_normal_error_deg"] = float(ang.max())
        else:
            out["detection_centre_error_m"] = None
    else:
        out.update({"min_clearance_m": None, "frames_passed": None, "detection_centre_error_m": None})
    landed = bool(p[-1, 2] < mission.pad_W[2] + 0.05)
    if course is not None:
        last = course.frames[-1]
        landed = landed and float((p[-1] - np.asarray(last.centre_W)) @ last.axis_W) > 0.2
    out["landed_beyond_last_frame"] = landed
    out["success"] = bool(sim_status == "completed" and mission.state == "done" and passed_all and landed)
    out["plans"] = [
        {
            "t": round(r.t, 3),
            "leg": r.leg,
            "ok": r.ok,
            "reason": r.reason,
            "plan_ms": round(r.plan_ms, 2),
            "min_clearance_m": round(float(r.min_clearance_m), 4),
        }
        for r in mission.plans
    ]
    out["detections"] = len(mission.detections)
    out["estimator_unhealthy"] = [[round(a, 3), round(b, 3), c] for a, b, c in mission.health_events]
    out["estimator_unhealthy_s"] = round(float(sum(b for _, b, _ in mission.health_events)), 3)
    out["time_per_component_s"] = component_split(result.component_seconds)
    import time

    cpu = time.process_time() - mission.cpu_start_s  # every thread of the process, from the run's start
    out["cpu_time_s"] = round(cpu, 3)
    out["cpu_real_time_factor"] = float(result.sim_time_s / cpu) if cpu > 0 else None
    return out

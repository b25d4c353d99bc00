"""Planning metrics of a run: did the vehicle reach the goal without coming closer than the radius to an
obstacle, how far it flew, and how long its replans took.

Clearance is measured here, after the run, from the recorded true states to the world's true tree trunks (a
metric, never a flight input): every object labelled ``tree`` is taken as the vertical cylinder through its
mesh's vertices (centre = their mean in x-y, radius = their largest distance from it, so the clearance is
never overestimated), from the ground up to its top.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["planning_metrics", "tree_cylinders", "trunk_clearance"]


def tree_cylinders(world: Any) -> np.ndarray:
    """(K, 4) ``[x, y, radius, top z]`` of the objects labelled "tree" in ``world`` (empty without any)."""
    rows = []
    for obj in getattr(world, "objects", ()):
        if obj.label != "tree":
            continue
        v = np.asarray(obj.vertices)
        c = v[:, :2].mean(axis=0)
        rows.append((c[0], c[1], float(np.max(np.linalg.norm(v[:, :2] - c, axis=1))), float(v[:, 2].max())))
    return np.asarray(rows, dtype=float).reshape(-1, 4)


def trunk_clearance(p_W: np.ndarray, cylinders: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Distance from each point (N, 3) to the nearest trunk surface [m] (negative inside; inf without trunks)."""
    p = np.asarray(p_W, dtype=float).reshape(-1, 3)
    out = np.full(p.shape[0], np.inf)
    if cylinders.shape[0] == 0:
        return out
    for i in range(0, p.shape[0], chunk):
        q = p[i : i + chunk]
        radial = (
            np.hypot(q[:, None, 0] - cylinders[None, :, 0], q[:, None, 1] - cylinders[None, :, 1])
            - cylinders[None, :, 2]
        )
        above = q[:, None, 2] - cylinders[None, :, 3]  # > 0: above the top
        d = np.where(above > 0, np.hypot(np.maximum(radial, 0.0), above), radial)
        out[i : i + chunk] = d.min(axis=1)
    return out


def planning_metrics(
    result: Any, planner: Any, world: Any, start_W: np.ndarray, goal_tolerance: float = 0.3
) -> dict[str, Any]:
    """``success`` (the true position came within ``goal_tolerance`` [m] of the planner's goal — its
    ``active_goal``, moved at most its ``max_goal_shift`` off the requested one when that lies against an
    obstacle —, the run did not end in a collision, and the vehicle never came closer than the planner's
    radius to a trunk),
    ``min_clearance_m`` (over the whole flight), ``path_length_m`` (flown from the start until the goal was
    first reached, or the whole flight), and the replans' wall time (``plan_ms_*``) and CPU time (``plan_cpu_ms_*``:
    the wall time less preemption, which dominates the wall time's tail on a loaded machine), status counts and the smallest map clearance
    of an accepted trajectory."""
    t, p = result.states["t"], result.states["p_W"]
    goal = np.asarray(planner.active_goal, dtype=float)
    dist_goal = np.linalg.norm(p - goal, axis=1)
    reached = np.flatnonzero(dist_goal <= goal_tolerance)
    end = int(reached[0]) + 1 if reached.size else p.shape[0]
    clearance = trunk_clearance(p, tree_cylinders(world)) if world is not None else np.full(len(t), np.inf)
    min_clear = float(clearance.min()) if clearance.size else float("inf")
    radius = float(planner.params.radius)
    ms = np.array([r.plan_ms for r in planner.replans], dtype=float)
    cpu_ms = np.array([getattr(r, "plan_cpu_ms", np.nan) for r in planner.replans], dtype=float)
    cpu_ms = cpu_ms[np.isfinite(cpu_ms)]
    accepted = [r for r in planner.replans if r.status == "ok"]
    statuses: dict[str, int] = {}
    for r in planner.replans:
        statuses[r.status] = statuses.get(r.status, 0) + 1
    collided = getattr(result.status, "value", str(result.status)) == "collision"
    return {
        "success": bool(reached.size > 0 and not collided and min_clear >= radius),
        "goal_reached": bool(reached.size > 0),
        "goal_reached_s": float(t[reached[0]]) if reached.size else None,
        "goal_distance_min_m": float(dist_goal.min()) if dist_goal.size else None,
        "goal_shift_m": float(np.linalg.norm(goal - np.asarray(planner.goal_W, dtype=float))),
        "min_clearance_m": min_clear if np.isfinite(min_clear) else None,
        "clearance_radius_m": radius,
        "path_length_m": float(np.sum(np.linalg.norm(np.diff(p[:end], axis=0), axis=1))),
        "straight_line_m": float(np.linalg.norm(goal - np.asarray(start_W, dtype=float))),
        "replans": len(planner.replans),
        "replan_status": statuses,
        "plan_ms_median": float(np.median(ms)) if ms.size else None,
        "plan_ms_p99": float(np.percentile(ms, 99)) if ms.size else None,
        "plan_ms_max": float(ms.max()) if ms.size else None,
        "plan_cpu_ms_median": float(np.median(cpu_ms)) if cpu_ms.size else None,
        "plan_cpu_ms_p99": float(np.percentile(cpu_ms, 99)) if cpu_ms.size else None,
        "plan_min_map_clearance_m": float(min(r.min_clearance_m for r in accepted)) if accepted else None,
    }

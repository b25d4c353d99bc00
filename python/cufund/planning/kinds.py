"""The built-in planner kinds of scenarios."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..registry import Kind, register
from .minimum_snap import MinimumSnapTrajectory
from .point_to_point import JerkLimitedMove
from .sequence import Hold, TrajectorySequence
from .trajectory_follower import TrajectoryFollower


@dataclass(frozen=True)
class WaypointsParams:
    """Flies the scenario's ``trajectory`` section; no keys of its own."""


def build_reference(cfg: Any) -> tuple[TrajectorySequence, MinimumSnapTrajectory]:
    """Take-off from below the first waypoint, hover, minimum-snap through the waypoints, hover, landing below the
    last one (``cfg`` is a :class:`cufund.scenario.TrajectoryConfig`). Returns the whole reference and its
    min-snap part."""
    w = np.asarray(cfg.waypoints)
    yaw = None if cfg.yaw is None else np.asarray(cfg.yaw)
    yaw0 = 0.0 if yaw is None else float(yaw[0])
    ground = np.array([w[0, 0], w[0, 1], 0.0])
    takeoff = JerkLimitedMove(ground, w[0], cfg.move_v_max, cfg.move_a_max, cfg.move_j_max, yaw0, t_start=0.0)
    hover1 = Hold(w[0], cfg.hover_s, yaw0, t_start=takeoff.t_end)
    if cfg.corridor is None and not cfg.optimize_times:
        path = MinimumSnapTrajectory(w, yaw, v_max=cfg.v_max, a_max=cfg.a_max, t_start=hover1.t_end)
    else:  # the planner that optimises times and inserts waypoints where the path leaves the corridor
        from .min_snap_planner import MinSnapPlanner, MinSnapPlannerParams

        planner = MinSnapPlanner(MinSnapPlannerParams(cfg.v_max, cfg.a_max, optimize_times=cfg.optimize_times,
                                                      corridor=cfg.corridor))
        result = planner.plan(w, yaw, t_start=hover1.t_end)
        if result.status != "ok":
            raise ValueError(f"trajectory.corridor: no min-snap path stays within {cfg.corridor} m of the "
                             f"waypoints ({result.status})")
        path = result.trajectory
    yaw_end = float(path.yaw_waypoints[-1])
    hover2 = Hold(w[-1], cfg.hover_s, yaw_end, t_start=path.t_end)
    landing = JerkLimitedMove(w[-1], np.array([w[-1, 0], w[-1, 1], 0.0]), cfg.move_v_max, cfg.move_a_max,
                              cfg.move_j_max, yaw_end, t_start=hover2.t_end)
    return TrajectorySequence([takeoff, hover1, path, hover2, landing]), path


def _waypoints(p: WaypointsParams, ctx: Any) -> list[Any]:
    reference, path = build_reference(ctx.trajectory())
    follower = TrajectoryFollower(reference, rate_hz=ctx.config.rates.trajectory_hz)
    ctx.set_reference(reference, path)
    return [follower]


register(Kind("planner", "waypoints", WaypointsParams, _waypoints, None,
              "take off, fly a minimum-snap path through trajectory.waypoints, land below the last one"))

"""The planning pipeline of paper §2.3 in one call: task (LTLf) -> path (grid A* legs) -> motion (min-snap).

``plan_mission_trajectory`` turns a :class:`MissionSpec` into the ordered region visits and their
waypoints, joins consecutive waypoints with certified-free grid A* legs (radius + margin), and smooths
the polyline into a minimum-snap trajectory that keeps ``radius`` of clearance (waypoints inserted where
it would not) within the speed and acceleration limits.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cufund.core.config import ConfigError

from .clearance import ClearanceQuery
from .min_snap_planner import MinSnapPlanner, MinSnapPlannerParams, MinSnapResult
from .mission_spec import MissionPlan, MissionSpec, Region
from .path_search import GridPathSearch, GridPathSearchParams

__all__ = ["MissionTrajectory", "plan_mission_trajectory"]


@dataclass(frozen=True)
class MissionTrajectory:
    """The three stages' outputs."""

    mission: MissionPlan
    """Regions in visiting order and their waypoints."""
    path_W: np.ndarray
    """(K, 3) certified-free polyline from the start through every waypoint [m]."""
    motion: MinSnapResult
    """The trajectory (``motion.trajectory``) and its feasibility report."""


def plan_mission_trajectory(
    spec: MissionSpec,
    regions: Mapping[str, Region] | list[Region],
    start_W: npt.ArrayLike,
    query: ClearanceQuery,
    radius: float,
    v_max: float = 1.0,
    a_max: float = 2.0,
    path_margin: float = 0.02,
    t_start: float = 0.0,
) -> MissionTrajectory:
    """Plans ``spec`` from ``start_W`` (3,) [m] on the map of ``query``; ConfigError if a stage fails."""
    mission = spec.plan(regions, start_W)
    search = GridPathSearch(GridPathSearchParams(radius=radius + path_margin))
    points = [np.asarray(start_W, dtype=float)]
    for name, wp in zip(mission.regions, mission.waypoints_W, strict=True):
        leg = search.plan(query, points[-1], wp)
        if not leg.found:
            raise ConfigError(
                f"no path to region {name!r} at {wp.tolist()} ({leg.status}) with clearance {radius + path_margin} m"
            )
        points.extend(leg.path_W[1:])
    path = np.array(points)
    motion = MinSnapPlanner(MinSnapPlannerParams(v_max=v_max, a_max=a_max, radius=radius)).plan(
        path, query=query, t_start=t_start
    )
    if motion.status != "ok":
        raise ConfigError(f"the min-snap trajectory could not be made to keep {radius} m of clearance")
    return MissionTrajectory(mission, path, motion)

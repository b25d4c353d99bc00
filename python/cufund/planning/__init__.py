"""Trajectories and planners (paper §3.1)."""

from cufund.core.components import Planner

from .bspline import UniformBspline
from .clearance import ClearanceQuery
from .feasibility import TrajectoryFeasibility, feasibility
from .global_planner import GlobalPlan, GlobalPlanner, GlobalPlannerParams
from .local_planner import BsplineLocalPlanner, LocalPlan, LocalPlannerParams
from .min_snap_planner import MinSnapPlanner, MinSnapPlannerParams, MinSnapResult
from .minimum_snap import MinimumSnapTrajectory, allocate_segment_times, min_derivative_spline, optimize_segment_times
from .mission_spec import MissionPlan, MissionSpec, Region
from .mission_trajectory import MissionTrajectory, plan_mission_trajectory
from .ompl_path import OmplPathParams, OmplPathPlanner
from .path_search import GridPathSearch, GridPathSearchParams, PathResult
from .point_to_point import JerkLimitedMove
from .sequence import Hold, TrajectorySequence
from .trajectory import Trajectory, TrajectorySamples
from .trajectory_follower import TrajectoryFollower
from .world_map import clearance_from_world, esdf_from_world, world_occupancy

__all__ = [
    "BsplineLocalPlanner",
    "ClearanceQuery",
    "GlobalPlan",
    "GlobalPlanner",
    "GlobalPlannerParams",
    "GridPathSearch",
    "GridPathSearchParams",
    "Hold",
    "JerkLimitedMove",
    "LocalPlan",
    "LocalPlannerParams",
    "MinSnapPlanner",
    "MinSnapPlannerParams",
    "MinSnapResult",
    "MinimumSnapTrajectory",
    "MissionPlan",
    "MissionSpec",
    "MissionTrajectory",
    "OmplPathParams",
    "OmplPathPlanner",
    "PathResult",
    "Region",
    "TrajectorySequence",
    "Planner",
    "Trajectory",
    "TrajectoryFeasibility",
    "TrajectoryFollower",
    "TrajectorySamples",
    "UniformBspline",
    "feasibility",
    "allocate_segment_times",
    "optimize_segment_times",
    "plan_mission_trajectory",
    "clearance_from_world",
    "esdf_from_world",
    "min_derivative_spline",
    "world_occupancy",
]

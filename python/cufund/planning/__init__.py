"""Trajectories and planners (paper §3.1)."""

from ..components import Planner
from .clearance import ClearanceQuery
from .minimum_snap import MinimumSnapTrajectory, allocate_segment_times, min_derivative_spline
from .ompl_path import OmplPathParams, OmplPathPlanner
from .path_search import GridPathSearch, GridPathSearchParams, PathResult
from .point_to_point import JerkLimitedMove
from .sequence import Hold, TrajectorySequence
from .trajectory import Trajectory, TrajectorySamples
from .trajectory_follower import TrajectoryFollower
from .world_map import esdf_from_world

__all__ = ["ClearanceQuery", "GridPathSearch", "GridPathSearchParams", "Hold", "JerkLimitedMove", "MinimumSnapTrajectory",
           "OmplPathParams", "OmplPathPlanner", "PathResult", "TrajectorySequence", "Planner", "Trajectory",
           "TrajectoryFollower", "TrajectorySamples", "allocate_segment_times", "esdf_from_world",
           "min_derivative_spline"]

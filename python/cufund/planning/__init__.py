"""Trajectories and planners (paper §3.1)."""

from ..components import Planner
from .minimum_snap import MinimumSnapTrajectory, allocate_segment_times, min_derivative_spline
from .trajectory import Trajectory, TrajectorySamples
from .trajectory_follower import TrajectoryFollower

__all__ = ["MinimumSnapTrajectory", "Planner", "Trajectory", "TrajectoryFollower", "TrajectorySamples",
           "allocate_segment_times", "min_derivative_spline"]

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


@dataclass(frozen=True)
class LocalParams:
    """Take off, then replan a B-spline towards ``goal`` on the growing ESDF map (needs the ``esdf`` mapper),
    hover at the goal and land. Lengths [m], times [s]."""

    goal: tuple[float, float, float] = (30.0, 0.0, 1.5)
    """Goal, world ENU [m]."""
    takeoff_height: float = 1.5
    """Height of the take-off above the start [m]."""
    rate_hz: float = 10.0
    """Replan rate [Hz]."""
    goal_tolerance: float = 0.1
    """The reference has arrived when it rests this close to the goal [m]."""
    hover_s: float = 1.0
    """Hover at the take-off height and at the goal [s]."""
    move_v_max: float = 0.5
    """Take-off and landing speed limit [m/s]."""
    move_a_max: float = 1.0
    """Take-off and landing acceleration limit [m/s^2]."""
    move_j_max: float = 3.0
    """Take-off and landing jerk limit [m/s^3]."""
    radius: float = 0.3
    """Clearance every accepted trajectory keeps on the map [m] (LocalPlannerParams.radius)."""
    margin: float = 0.3
    """Extra distance the collision cost acts within [m]."""
    v_max: float = 2.0
    """Speed limit per axis [m/s]."""
    a_max: float = 3.0
    """Acceleration limit per axis [m/s^2]."""
    dt: float = 0.15
    """B-spline knot interval [s]."""
    horizon: float = 7.0
    """Guide-path length one replan covers [m]."""
    max_iterations: int = 100
    """Optimiser iterations per replan."""

    def __post_init__(self) -> None:
        from ..config import ConfigError, vector3

        object.__setattr__(self, "goal", vector3("planner.goal", self.goal, " [m]", finite=True))
        if self.goal[2] <= 0.1:
            raise ConfigError(f"planner.goal must be above 0.1 m, got {self.goal!r}")
        for name in ("takeoff_height", "rate_hz", "goal_tolerance", "move_v_max", "move_a_max", "move_j_max"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
                raise ConfigError(f"planner.{name} must be a finite number > 0, got {v!r}")
        if isinstance(self.hover_s, bool) or not isinstance(self.hover_s, (int, float)) \
                or not (np.isfinite(self.hover_s) and self.hover_s >= 0):
            raise ConfigError(f"planner.hover_s must be a finite number >= 0 [s], got {self.hover_s!r}")

    def planner_params(self) -> Any:
        from ..config import ConfigError
        from .local_planner import LocalPlannerParams

        try:
            return LocalPlannerParams(radius=self.radius, margin=self.margin, v_max=self.v_max, a_max=self.a_max,
                                      dt=self.dt, horizon=self.horizon, max_iterations=self.max_iterations)
        except ConfigError as e:
            raise ConfigError(f"planner.{e}") from None


def _local(p: LocalParams, ctx: Any) -> list[Any]:
    from ..messages import Topics
    from .local_planner_component import LocalPlannerComponent
    from .metrics import planning_metrics

    cfg = ctx.config
    w0 = cfg.trajectory.waypoints[0]
    start = np.array(cfg.start_p_W if cfg.start_p_W is not None else (w0[0], w0[1], 0.0), dtype=float)
    top = start + np.array([0.0, 0.0, p.takeoff_height])
    takeoff = JerkLimitedMove(start, top, p.move_v_max, p.move_a_max, p.move_j_max, 0.0, t_start=0.0)
    initial = TrajectorySequence([takeoff, Hold(top, p.hover_s, 0.0, t_start=takeoff.t_end)])
    planner = LocalPlannerComponent(p.planner_params(), p.goal, initial, t_begin=initial.t_end, rate_hz=p.rate_hz,
                                    goal_tolerance=p.goal_tolerance, hover_s=p.hover_s,
                                    landing=(p.move_v_max, p.move_a_max, p.move_j_max))
    follower = TrajectoryFollower(initial, rate_hz=cfg.rates.trajectory_hz, block=32,
                                  update_topic=Topics.TRAJECTORY_UPDATE)

    def landed(t: float, truth: Any) -> bool:  # run end: landed after the goal (a run-harness check)
        return planner.t_landed is not None and t >= planner.t_landed and truth.p_W[2] < start[2] + 0.02 \
            and float(np.linalg.norm(truth.v_W)) < 0.05

    ctx.done = landed
    ctx.metric_hooks.append(lambda result: planning_metrics(result, planner, ctx.world, start))
    return [planner, follower]


register(Kind("planner", "local", LocalParams, _local, None,
              "take off, replan a B-spline on the growing ESDF map (mapper: esdf) to planner.goal, land there"))

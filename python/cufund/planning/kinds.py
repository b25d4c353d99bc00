"""The built-in planner kinds of scenarios."""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most
from cufund.core.registry import Kind, register

from .minimum_snap import MinimumSnapTrajectory
from .path_search import GridPathSearchParams
from .point_to_point import JerkLimitedMove
from .sequence import Hold, TrajectorySequence
from .trajectory_follower import TrajectoryFollower


def _positive(params: Any, names: tuple[str, ...], unit: str) -> None:
    """Each of ``names`` must be a finite number > 0 [unit]: else a ConfigError naming the field."""
    for name in names:
        v = getattr(params, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
            raise ConfigError(f"planner.{name} must be a finite number > 0 [{unit}], got {v!r}")


@dataclass(frozen=True)
class WaypointsParams:
    """Flies the scenario's ``trajectory`` section; no keys of its own."""


def build_reference(cfg: Any) -> tuple[TrajectorySequence, MinimumSnapTrajectory]:
    """Take-off from below the first waypoint, hover, minimum-snap through the waypoints, hover, landing below the
    last one (``cfg`` is a :class:`cufund.scenarios.TrajectoryConfig`). Returns the whole reference and its
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

        planner = MinSnapPlanner(
            MinSnapPlannerParams(cfg.v_max, cfg.a_max, optimize_times=cfg.optimize_times, corridor=cfg.corridor)
        )
        result = planner.plan(w, yaw, t_start=hover1.t_end)
        if result.status != "ok":
            raise ValueError(
                f"trajectory.corridor: no min-snap path stays within {cfg.corridor} m of the "
                f"waypoints ({result.status})"
            )
        path = result.trajectory
    yaw_end = float(path.yaw_waypoints[-1])
    hover2 = Hold(w[-1], cfg.hover_s, yaw_end, t_start=path.t_end)
    landing = JerkLimitedMove(
        w[-1],
        np.array([w[-1, 0], w[-1, 1], 0.0]),
        cfg.move_v_max,
        cfg.move_a_max,
        cfg.move_j_max,
        yaw_end,
        t_start=hover2.t_end,
    )
    return TrajectorySequence([takeoff, hover1, path, hover2, landing]), path


def _waypoints(p: WaypointsParams, ctx: BuildContext) -> list[Any]:
    reference, path = build_reference(ctx.config.trajectory)
    follower = TrajectoryFollower(reference, rate_hz=ctx.config.rates.trajectory_hz)
    ctx.set_reference(reference, path)
    return [follower]


register(
    Kind(
        "planner",
        "waypoints",
        WaypointsParams,
        _waypoints,
        None,
        "take off, fly a minimum-snap path through trajectory.waypoints, land below the last one",
    )
)


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
    z_min: float = 0.5
    """Flight band of the replanner, lowest height [m] (unobserved ground is free to the map)."""
    z_max: float = 3.0
    """Flight band of the replanner, highest height [m]."""

    def __post_init__(self) -> None:
        from cufund.core.config import ConfigError, vector3

        object.__setattr__(self, "goal", vector3("planner.goal", self.goal, " [m]", finite=True))
        if self.goal[2] <= 0.1:
            raise ConfigError(f"planner.goal must be above 0.1 m, got {self.goal!r}")
        for name in ("takeoff_height", "rate_hz", "goal_tolerance", "move_v_max", "move_a_max", "move_j_max"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0):
                raise ConfigError(f"planner.{name} must be a finite number > 0, got {v!r}")
        if (
            isinstance(self.hover_s, bool)
            or not isinstance(self.hover_s, (int, float))
            or not (np.isfinite(self.hover_s) and self.hover_s >= 0)
        ):
            raise ConfigError(f"planner.hover_s must be a finite number >= 0 [s], got {self.hover_s!r}")
        check_at_most(self, "planner", rate_hz=1e3, horizon=1e3, max_iterations=10_000)

    def planner_params(self) -> Any:
        from cufund.core.config import ConfigError

        from .local_planner import LocalPlannerParams

        try:
            return LocalPlannerParams(
                radius=self.radius,
                margin=self.margin,
                v_max=self.v_max,
                a_max=self.a_max,
                dt=self.dt,
                horizon=self.horizon,
                max_iterations=self.max_iterations,
                z_min=self.z_min,
                z_max=self.z_max,
            )
        except ConfigError as e:
            raise ConfigError(f"planner.{e}") from None


def _start(ctx: BuildContext) -> np.ndarray:
    cfg = ctx.config
    w0 = cfg.trajectory.waypoints[0]
    return np.array(cfg.start_p_W if cfg.start_p_W is not None else (w0[0], w0[1], 0.0), dtype=float)


def _takeoff(p: LocalParams, ctx: BuildContext) -> tuple[np.ndarray, TrajectorySequence]:
    """The start and the reference until the first plan: take-off to ``takeoff_height``, hover ``hover_s``."""
    start = _start(ctx)
    top = start + np.array([0.0, 0.0, p.takeoff_height])
    takeoff = JerkLimitedMove(start, top, p.move_v_max, p.move_a_max, p.move_j_max, 0.0, t_start=0.0)
    return start, TrajectorySequence([takeoff, Hold(top, p.hover_s, 0.0, t_start=takeoff.t_end)])


def _replanned(ctx: BuildContext, planner: Any, initial: Any, start: np.ndarray, extra: Any = None) -> list[Any]:
    """The follower stitching ``planner``'s updates into ``initial``; the run ends once landed after the goal;
    ``metrics.json`` gains the planning metrics (and ``extra()``'s)."""
    from cufund.core.messages import Topics

    from .metrics import planning_metrics

    follower = TrajectoryFollower(
        initial, rate_hz=ctx.config.rates.trajectory_hz, block=32, update_topic=Topics.TRAJECTORY_UPDATE
    )

    def landed(t: float, truth: Any) -> bool:  # run end: landed after the goal (a run-harness check)
        return (
            planner.t_landed is not None
            and t >= planner.t_landed
            and truth.p_W[2] < start[2] + 0.02
            and float(np.linalg.norm(truth.v_W)) < 0.05
        )

    ctx.set_done_condition(landed)
    # The world is read after the run, by the metric alone (clearance to the true trunks): never by the planner.
    ctx.add_metric_hook(
        lambda result: {
            **planning_metrics(result, planner, ctx.truth_world_for_metrics(), start),
            **(extra() if extra is not None else {}),
        }
    )
    return [planner, follower]


def _local(p: LocalParams, ctx: BuildContext, guide_W: np.ndarray | None = None) -> list[Any]:
    from .local_planner_component import LocalPlannerComponent

    start, initial = _takeoff(p, ctx)
    planner = LocalPlannerComponent(
        p.planner_params(),
        p.goal,
        initial,
        t_begin=initial.t_end,
        rate_hz=p.rate_hz,
        goal_tolerance=p.goal_tolerance,
        hover_s=p.hover_s,
        landing=(p.move_v_max, p.move_a_max, p.move_j_max),
        guide_W=guide_W,
    )
    return _replanned(ctx, planner, initial, start)


register(
    Kind(
        "planner",
        "local",
        LocalParams,
        _local,
        None,
        "take off, replan a B-spline on the growing ESDF map (mapper: esdf) to planner.goal, land there",
    )
)


@dataclass(frozen=True)
class _ChainParams(LocalParams):
    """The keys the global planners share: path search (``search``) -> min-snap keeping ``radius``; then fly it
    (``local: false``: hover at the goal and land) or hand the path to the local replanner as its guide on the
    growing map (``local: true``, needs the ``esdf`` mapper). Lengths [m], times [s]; the other keys are the
    ``local`` kind's."""

    search: str = "astar"
    """Path search: astar (deterministic grid A*), rrt_connect, informed_rrt_star or bit_star (OMPL)."""
    path_margin: float = 0.05
    """The path is searched with radius + path_margin [m]."""
    optimize_times: bool = True
    """Min-snap segment times optimised for least snap before scaling to v_max / a_max."""
    heuristic_weight: float = GridPathSearchParams.heuristic_weight
    """Grid A* heuristic weight (>= 1)."""
    time_limit: float = 1.0
    """OMPL: wall time for a first solution [s]."""
    improve_time: float = 1.0
    """OMPL informed_rrt_star / bit_star: wall time for improving it [s]."""
    local: bool = False
    """Feed the path to the local replanner instead of flying the min-snap."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.local, bool):
            raise ConfigError(f"planner.local must be true or false, got {self.local!r}")
        self.global_params()

    def _band(self) -> tuple[float, float]:
        """The grid A*'s height band (z_min, z_max) [m]: unbounded on a known geometry."""
        return (-math.inf, math.inf)

    def global_params(self) -> Any:
        from .global_planner import GlobalPlannerParams

        try:
            return GlobalPlannerParams(
                search=self.search,
                radius=self.radius,
                margin=self.path_margin,
                v_max=self.v_max,
                a_max=self.a_max,
                optimize_times=self.optimize_times,
                heuristic_weight=self.heuristic_weight,
                time_limit=self.time_limit,
                improve_time=self.improve_time,
                z_min=self._band()[0],
                z_max=self._band()[1],
            )
        except ConfigError as e:
            msg = str(e)
            raise ConfigError(f"planner.{'path_' + msg if msg.startswith('margin') else msg}") from None


@dataclass(frozen=True)
class GlobalParams(_ChainParams):
    """Take off, then plan on the map built online (the ``esdf`` mapper's ``/map/esdf``, in the estimate's
    frame; unknown space counts as free, the search keeps to the flight band z_min..z_max): path search -> min-snap
    keeping ``radius``, flown (``local: false``: braked and replanned from rest when the newest map blocks it) or
    the local replanner's guide (``local: true``: searched again when the map blocks it or every
    ``replan_interval_s``). Gives up after ``give_up_s`` without a plan: hover, land. Lengths [m], times [s]."""

    replan_interval_s: float = 1.0
    """local: true: the guide is searched again at least this often [s] (and whenever the map blocks it)."""
    give_up_s: float = 5.0
    """Hover and land when no plan has succeeded for this long [s] (goal unreachable on the map)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        _positive(self, ("replan_interval_s", "give_up_s"), "s")

    def _band(self) -> tuple[float, float]:
        return (self.z_min, self.z_max)  # the online map's unobserved ground is free: keep to the flight band


@dataclass(frozen=True)
class GlobalKnownMapParams(_ChainParams):
    """Take off, plan once on the world's TRUE geometry (a certified distance field of its triangles), fly the
    plan or guide the local replanner with it. A truth consumer: what a vehicle cannot know (every trunk, also
    the unseen ones); a planner-only reference, never a headline figure. Lengths [m], times [s]."""

    resolution: float = 0.1
    """Voxel edge of the known-geometry distance field [m]."""
    map_padding: float = 6.0
    """The field covers the start and goal's bounding box grown by this much sideways and 2 m up [m]."""

    def __post_init__(self) -> None:
        super().__post_init__()
        _positive(self, ("resolution", "map_padding"), "m")


def _global(p: GlobalParams, ctx: BuildContext) -> list[Any]:
    """The global planner on the online map: no world is read (the map comes over the bus)."""
    from .global_planner import GlobalPlanner
    from .global_planner_component import GlobalPlannerComponent

    start, initial = _takeoff(p, ctx)
    planner = GlobalPlannerComponent(
        GlobalPlanner(p.global_params()),
        p.planner_params(),
        p.goal,
        initial,
        t_begin=initial.t_end,
        rate_hz=p.rate_hz,
        goal_tolerance=p.goal_tolerance,
        hover_s=p.hover_s,
        landing=(p.move_v_max, p.move_a_max, p.move_j_max),
        local=p.local,
        replan_interval_s=p.replan_interval_s,
        give_up_s=p.give_up_s,
    )
    return _replanned(ctx, planner, initial, start, planner.global_metrics)


register(
    Kind(
        "planner",
        "global",
        GlobalParams,
        _global,
        None,
        "take off, plan on the map built online (A* or OMPL -> clearance-keeping min-snap) to planner.goal, "
        "replanned when the map blocks it; fly it and land, or (local: true) guide the local replanner with it",
    )
)


def _global_known_map(p: GlobalKnownMapParams, ctx: BuildContext) -> list[Any]:
    from .global_planner import GlobalPlanner
    from .global_planner_component import plan_metrics
    from .local_planner_component import ReplanRecord
    from .metrics import planning_metrics
    from .world_map import clearance_from_world

    world = ctx.require_world()  # the true world: this kind is a truth consumer (see GlobalKnownMapParams)
    start = _start(ctx)
    top = start + np.array([0.0, 0.0, p.takeoff_height])
    goal = np.asarray(p.goal, dtype=float)
    lo = np.minimum(top, goal) - [p.map_padding, p.map_padding, 0.0]
    hi = np.maximum(top, goal) + [p.map_padding, p.map_padding, 2.0]
    lo[2] = min(0.0, float(start[2]))
    query = clearance_from_world(world, p.resolution, np.stack([lo, hi]))
    takeoff = JerkLimitedMove(start, top, p.move_v_max, p.move_a_max, p.move_j_max, 0.0, t_start=0.0)
    hover1 = Hold(top, p.hover_s, 0.0, t_start=takeoff.t_end)
    plan = GlobalPlanner(p.global_params()).plan(query, top, goal, t_start=hover1.t_end)
    if not plan.ok:
        raise ConfigError(
            f"planner: no {p.search} plan from {top.tolist()} to {list(p.goal)} keeping "
            f"{p.radius} m (+ {p.path_margin} m for the path) on the world's geometry ({plan.status})"
        )
    motion = plan.motion
    assert motion is not None  # a plan that succeeded has its motion (checked just above)
    stats = plan_metrics(plan, p.search)
    if p.local:
        parts = _local(p, ctx, guide_W=plan.path.path_W)
        ctx.add_metric_hook(lambda result: stats)
        return parts
    path = motion.trajectory
    hover2 = Hold(goal, p.hover_s, 0.0, t_start=path.t_end)
    landing = JerkLimitedMove(
        goal,
        np.array([goal[0], goal[1], start[2]]),
        p.move_v_max,
        p.move_a_max,
        p.move_j_max,
        0.0,
        t_start=hover2.t_end,
    )
    reference = TrajectorySequence([takeoff, hover1, path, hover2, landing])
    follower = TrajectoryFollower(reference, rate_hz=ctx.config.rates.trajectory_hz)
    ctx.set_reference(reference, path)
    # The metrics of a replanning run, with the one plan as its only replan.
    curve = path.sample(np.arange(path.t_start, path.t_end, 0.01)).p_W
    record = ReplanRecord(
        hover1.t_end,
        plan.status,
        1e3 * plan.plan_seconds,
        motion.min_clearance,
        float(np.sum(np.linalg.norm(np.diff(curve, axis=0), axis=1))),
        1e3 * plan.plan_cpu_seconds,
    )
    once = SimpleNamespace(active_goal=goal, goal_W=goal, params=SimpleNamespace(radius=p.radius), replans=[record])
    ctx.add_metric_hook(lambda result: {**planning_metrics(result, once, world, start), **stats})
    return [follower]


register(
    Kind(
        "planner",
        "global_known_map",
        GlobalKnownMapParams,
        _global_known_map,
        None,
        "take off, plan once on the world's TRUE geometry (a truth consumer: a planner-only reference) to "
        "planner.goal; fly it and land, or (local: true) guide the local replanner with it",
    )
)

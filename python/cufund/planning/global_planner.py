"""The global planning chain of paper §2.3 for one start and goal: path search over a certified ESDF clearance
(the deterministic grid A*, or OMPL's RRTConnect / Informed RRT* / BIT*) -> clearance-keeping minimum-snap.

The path is searched with ``radius + margin`` so that :class:`MinSnapPlanner`'s waypoint insertion converges
(the spline approaches the polyline, which clears the radius by the margin); the trajectory keeps ``radius``
everywhere (certified at its 10 ms samples and the chords between them).
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cufund.core.config import ConfigError

from .clearance import ClearanceQuery
from .min_snap_planner import MinSnapPlanner, MinSnapPlannerParams, MinSnapResult
from .minimum_snap import MinimumSnapTrajectory
from .ompl_path import OmplPathParams, OmplPathPlanner
from .path_search import GridPathSearch, GridPathSearchParams, PathResult, check_flight_band

__all__ = ["SEARCHES", "GlobalPlan", "GlobalPlanner", "GlobalPlannerParams"]

SEARCHES = ("astar", "rrt_connect", "informed_rrt_star", "bit_star")
"""Path searches: the grid A* (deterministic, the default), OMPL's RRTConnect (first solution, simplified), or
RRTConnect then an optimising planner for ``improve_time`` seconds."""


def _number(name: str, v: object, lo: float, strict: bool) -> float:
    ok = (
        not isinstance(v, bool)
        and isinstance(v, numbers.Real)
        and math.isfinite(v)
        and (float(v) > lo if strict else float(v) >= lo)
    )
    if not ok:
        raise ConfigError(f"{name} must be a finite number {'>' if strict else '>='} {lo:g}, got {v!r}")
    return float(v)  # type: ignore[arg-type]


@dataclass(frozen=True)
class GlobalPlannerParams:
    """Parameters of :class:`GlobalPlanner`. Lengths [m], times [s]."""

    search: str = "astar"
    """One of :data:`SEARCHES`."""
    radius: float = 0.3
    """Clearance every point of the trajectory keeps [m]."""
    margin: float = 0.05
    """The path is searched with ``radius + margin`` [m] (the min-snap then converges onto it)."""
    v_max: float = 2.0
    """Speed limit [m/s] (min-snap times are scaled to it)."""
    a_max: float = 3.0
    """Acceleration limit [m/s^2]."""
    optimize_times: bool = True
    """Optimise the segment times for least snap (Mellinger & Kumar) before scaling to the limits."""
    heuristic_weight: float = GridPathSearchParams.heuristic_weight
    """Grid A*: weighted A* factor (>= 1)."""
    max_expansions: int = 5_000_000
    """Grid A*: expansion limit."""
    time_limit: float = 1.0
    """OMPL: wall time for the first solution [s]."""
    improve_time: float = 1.0
    """OMPL informed_rrt_star / bit_star: wall time for the optimising planner [s] (ignored otherwise)."""
    z_min: float = -math.inf
    """Grid A*: lowest height searched [m, world z] (:attr:`GridPathSearchParams.z_min`; the start and goal may lie
    outside the band). A map built online needs it: its unobserved ground is free. The OMPL searches sample the
    whole map box."""
    z_max: float = math.inf
    """Grid A*: highest height searched [m, world z]."""

    def __post_init__(self) -> None:
        if self.search not in SEARCHES:
            raise ConfigError(f"search must be one of {', '.join(SEARCHES)}, got {self.search!r}")
        for name in ("radius", "v_max", "a_max", "heuristic_weight", "time_limit"):
            object.__setattr__(self, name, _number(name, getattr(self, name), 0.0, True))
        for name in ("margin", "improve_time"):
            object.__setattr__(self, name, _number(name, getattr(self, name), 0.0, False))
        if self.heuristic_weight < 1.0:
            raise ConfigError(f"heuristic_weight must be >= 1, got {self.heuristic_weight!r}")
        if self.search in ("informed_rrt_star", "bit_star") and self.improve_time <= 0:
            raise ConfigError(f"improve_time must be > 0 [s] for search {self.search!r}, got {self.improve_time!r}")
        if not isinstance(self.optimize_times, (bool, np.bool_)):
            raise ConfigError(f"optimize_times must be a bool, got {self.optimize_times!r}")
        if (
            isinstance(self.max_expansions, bool)
            or not isinstance(self.max_expansions, numbers.Integral)
            or self.max_expansions < 1
        ):
            raise ConfigError(f"max_expansions must be an integer >= 1, got {self.max_expansions!r}")
        check_flight_band(self)


@dataclass(frozen=True)
class GlobalPlan:
    """The chain's outcome."""

    status: str
    """"ok"; the path search's status when it failed ("start_blocked", "goal_blocked", "no_path",
    "expansion_limit", "timeout"); "not_converged" (no min-snap kept the radius); or, from the online planner
    (:class:`~cufund.planning.global_planner_component.GlobalPlannerComponent`), "altitude" (the min-snap left the
    flight band)."""
    path: PathResult
    """The searched polyline (``path.path_W``), certified free at ``radius + margin``."""
    motion: MinSnapResult | None
    """The min-snap and its feasibility report (None when the search failed)."""
    search_seconds: float
    """Wall time of the path search [s]."""
    motion_seconds: float
    """Wall time of the min-snap stage [s]."""
    plan_cpu_seconds: float
    """CPU time of both stages [s]."""
    search_cpu_seconds: float
    """CPU time of the path search alone [s]."""

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def trajectory(self) -> MinimumSnapTrajectory | None:
        return None if self.motion is None else self.motion.trajectory

    @property
    def plan_seconds(self) -> float:
        return self.search_seconds + self.motion_seconds


class GlobalPlanner:
    """Search -> min-snap on a :class:`ClearanceQuery` (a live ESDF map or a static field of a known world)."""

    def __init__(self, params: GlobalPlannerParams | None = None) -> None:
        self.params = GlobalPlannerParams() if params is None else params
        if not isinstance(self.params, GlobalPlannerParams):
            raise TypeError(f"params must be a GlobalPlannerParams, got {type(params).__name__}")
        p = self.params
        r = p.radius + p.margin
        if p.search == "astar":
            self._search: GridPathSearch | OmplPathPlanner = GridPathSearch(
                GridPathSearchParams(
                    radius=r,
                    max_expansions=p.max_expansions,
                    heuristic_weight=p.heuristic_weight,
                    z_min=p.z_min,
                    z_max=p.z_max,
                )
            )
        else:
            improve = 0.0 if p.search == "rrt_connect" else p.improve_time
            optimizer = "bit_star" if p.search == "bit_star" else "informed_rrt_star"
            self._search = OmplPathPlanner(
                OmplPathParams(radius=r, time_limit=p.time_limit, improve_time=improve, optimizer=optimizer)
            )
        self._motion = MinSnapPlanner(
            MinSnapPlannerParams(v_max=p.v_max, a_max=p.a_max, radius=p.radius, optimize_times=bool(p.optimize_times))
        )

    def plan(
        self,
        query: ClearanceQuery,
        start_W: npt.ArrayLike,
        goal_W: npt.ArrayLike,
        t_start: float = 0.0,
        yaw: float = 0.0,
    ) -> GlobalPlan:
        """A trajectory from ``start_W`` to ``goal_W`` (3,) [m], at rest at both, starting at ``t_start`` [s]
        with constant ``yaw`` [rad]."""
        c0 = time.thread_time()
        path = self._path(query, start_W, goal_W)
        t1 = time.perf_counter()
        c1 = time.thread_time()
        if not path.found:
            return GlobalPlan(path.status, path, None, path.plan_seconds, 0.0, c1 - c0, c1 - c0)
        w = path.path_W
        motion = self._motion.plan(w, np.full(w.shape[0], float(yaw)), query=query, t_start=t_start)
        return GlobalPlan(
            "ok" if motion.status == "ok" else motion.status,
            path,
            motion,
            path.plan_seconds,
            time.perf_counter() - t1,
            time.thread_time() - c0,
            c1 - c0,
        )

    def search(self, query: ClearanceQuery, start_W: npt.ArrayLike, goal_W: npt.ArrayLike) -> GlobalPlan:
        """The path search alone (e.g. a guide for the local replanner): a :class:`GlobalPlan` without motion,
        status "ok" when a path was found."""
        c0 = time.thread_time()
        path = self._path(query, start_W, goal_W)
        cpu = time.thread_time() - c0
        return GlobalPlan("ok" if path.found else path.status, path, None, path.plan_seconds, 0.0, cpu, cpu)

    def _path(self, query: ClearanceQuery, start_W: npt.ArrayLike, goal_W: npt.ArrayLike) -> PathResult:
        if not isinstance(query, ClearanceQuery):
            raise TypeError(f"query must be a ClearanceQuery, got {type(query).__name__}")
        return self._search.plan(query, start_W, goal_W)

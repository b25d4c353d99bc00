"""Sampling-based path search with OMPL (PyPI ``ompl`` 2.x) over certified ESDF clearance.

RRTConnect finds a first solution; with ``improve_time`` > 0 an asymptotically optimal planner
(Informed RRT* or BIT*, path-length objective) runs for that long and the shorter path is kept; OMPL's
``PathSimplifier`` then shortcuts and reduces vertices. States are checked through the scalar C++
``clearance_xyz`` and motions through ``segment_free_xyz`` (sphere tracing), so every edge of the
result is certified to keep ``radius`` from every obstacle surface in the map. OMPL's sampling is
random: unlike :class:`~cufund.planning.GridPathSearch`, two runs may return different paths.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cufund.core.config import ConfigError

from .clearance import ClearanceQuery
from .path_search import PathResult, _radius

__all__ = ["OmplPathPlanner", "OmplPathParams"]

_OPTIMISERS = ("informed_rrt_star", "bit_star")


@dataclass(frozen=True)
class OmplPathParams:
    """Parameters of :class:`OmplPathPlanner`."""

    radius: float = 0.25
    """Required clearance [m] of every point of the path."""
    time_limit: float = 1.0
    """Wall time [s] RRTConnect may take for a first solution."""
    improve_time: float = 0.0
    """Extra wall time [s] for the optimising planner; 0 skips it."""
    optimizer: str = "informed_rrt_star"
    """"informed_rrt_star" or "bit_star"."""
    simplify: bool = True
    """Shortcut and reduce vertices with OMPL's PathSimplifier."""
    range: float = 0.0
    """Longest edge [m] the planners add (0: OMPL's default, a fraction of the space's extent)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _radius(self.radius))
        for name in ("time_limit", "improve_time", "range"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and float(v) >= 0):
                raise ConfigError(f"{name} must be a finite number >= 0 [s or m], got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.time_limit <= 0:
            raise ConfigError(f"time_limit must be > 0 [s], got {self.time_limit}")
        if self.optimizer not in _OPTIMISERS:
            raise ConfigError(f"optimizer must be one of {', '.join(_OPTIMISERS)}, got {self.optimizer!r}")
        if not isinstance(self.simplify, (bool, np.bool_)):
            raise ConfigError(f"simplify must be a bool, got {self.simplify!r}")


class OmplPathPlanner:
    """OMPL path search in the ESDF map's box, with the map's certified clearance as validity."""

    def __init__(self, params: OmplPathParams | None = None) -> None:
        self.params = OmplPathParams() if params is None else params
        if not isinstance(self.params, OmplPathParams):
            raise TypeError(f"params must be an OmplPathParams, got {type(params).__name__}")

    def plan(self, query: ClearanceQuery, start_W: npt.ArrayLike, goal_W: npt.ArrayLike) -> PathResult:
        """A path from ``start_W`` to ``goal_W`` (3,) [m]; status "timeout" if none within the time."""
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        if not isinstance(query, ClearanceQuery):
            raise TypeError(f"query must be a ClearanceQuery, got {type(query).__name__}")
        p = self.params
        start, goal = _point("start_W", start_W), _point("goal_W", goal_W)
        t0 = time.perf_counter()
        r = p.radius
        if not query.clearance(start) >= r:
            return _empty("start_blocked", t0)
        if not query.clearance(goal) >= r:
            return _empty("goal_blocked", t0)
        ou.setLogLevel(ou.LOG_WARN)
        lo, hi = query.bounds_W
        space = ob.RealVectorStateSpace(3)
        bounds = ob.RealVectorBounds(3)
        for i in range(3):
            bounds.setLow(i, float(lo[i]))
            bounds.setHigh(i, float(hi[i]))
        space.setBounds(bounds)
        clearance, seg = query.clearance_xyz, query.segment_free_xyz

        def valid(s: object) -> bool:
            return clearance(s[0], s[1], s[2]) >= r  # type: ignore[index]

        class Motion(ob.MotionValidator):
            def checkMotion(self, s1: object, s2: object, *last_valid: object) -> bool:
                return seg(s1[0], s1[1], s1[2], s2[0], s2[1], s2[2], r)  # type: ignore[index]

        def setup(planner_cls: Any) -> tuple[Any, Any]:
            ss = og.SimpleSetup(space)
            ss.setStateValidityChecker(valid)
            si = ss.getSpaceInformation()
            si.setMotionValidator(Motion(si))
            a, b = space.allocState(), space.allocState()
            for i in range(3):
                a[i], b[i] = float(start[i]), float(goal[i])
            ss.setStartAndGoalStates(a, b)
            planner = planner_cls(si)
            if p.range > 0:
                planner.setRange(p.range)
            ss.setPlanner(planner)
            return ss, si

        ss, si = setup(og.RRTConnect)
        ss.solve(p.time_limit)
        best = _path(ss) if ss.haveExactSolutionPath() else None
        if p.improve_time > 0:
            ss2, si2 = setup(og.InformedRRTstar if p.optimizer == "informed_rrt_star" else og.BITstar)
            ss2.setOptimizationObjective(ob.PathLengthOptimizationObjective(si2))
            ss2.solve(p.improve_time)
            if ss2.haveExactSolutionPath():
                cand = _path(ss2)
                if best is None or _length(cand[1]) < _length(best[1]):
                    best, si = cand, si2
        if best is None:
            return _empty("timeout", t0)
        path, pts = best
        if p.simplify:
            og.PathSimplifier(si).simplifyMax(path)
            pts = _states(path)
            pts = query.shortcut(pts, r)
        return PathResult(status="found", path_W=pts, length=_length(pts), plan_seconds=time.perf_counter() - t0)


def _path(ss: object) -> tuple[object, np.ndarray]:
    path = ss.getSolutionPath()  # type: ignore[attr-defined]
    return path, _states(path)


def _states(path: object) -> np.ndarray:
    n = path.getStateCount()  # type: ignore[attr-defined]
    return np.array([[path.getState(i)[j] for j in range(3)] for i in range(n)], dtype=float)  # type: ignore[attr-defined]


def _length(pts: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))


def _empty(status: str, t0: float) -> PathResult:
    return PathResult(status=status, path_W=np.zeros((0, 3)), length=0.0, plan_seconds=time.perf_counter() - t0)


def _point(name: str, p: npt.ArrayLike) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers [m], got {p!r}")
    return a

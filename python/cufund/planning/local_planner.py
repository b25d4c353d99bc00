"""ESDF-gradient B-spline local replanner (the Fast-Planner / EGO-Planner family).

Each replan starts from the vehicle's current position, velocity and acceleration (the first three
control points are fixed by them, so the new trajectory joins the old one with no jump in position,
velocity or acceleration), follows a guide path towards the goal (the grid A* on the current map,
a straight line when that fails), and optimises the free control points with L-BFGS on

    w_smooth * sum |jerk control points|^2 + w_collision * sum max(0, d_safe - d(Q_i))^3
    + w_feasibility * (speed and acceleration excess per axis)^2 + w_end * |Q_last - horizon point|^2

with d and its gradient the map's trilinear ESDF (control points bound the curve: convex hull). The
result is accepted only if the certified clearance along the curve (sampled every 10 ms, the chords
between the samples traced) is at least ``radius``; otherwise the status says why and the caller keeps the previous trajectory.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cufund import _core
from cufund.core.config import ConfigError
from cufund.mapping.esdf_map import EsdfMap

from .bspline import UniformBspline, start_control_points
from .clearance import ClearanceQuery
from .path_search import GridPathSearch, GridPathSearchParams

__all__ = ["BsplineLocalPlanner", "LocalPlan", "LocalPlannerParams"]


@dataclass(frozen=True)
class LocalPlannerParams:
    """Parameters of :class:`BsplineLocalPlanner`. Lengths [m], times [s]."""

    radius: float = 0.3
    """Clearance every point of an accepted trajectory keeps (certified against the map) [m]."""
    margin: float = 0.3
    """The collision cost acts below radius + margin (+ half a voxel diagonal) [m]."""
    v_max: float = 2.0
    """Speed limit per axis [m/s]."""
    a_max: float = 3.0
    """Acceleration limit per axis [m/s^2]."""
    dt: float = 0.15
    """Knot interval of the B-spline [s]."""
    horizon: float = 7.0
    """Length of guide path a replan covers [m]."""
    w_smooth: float = 1.0
    """Weight of the jerk control points' squares."""
    w_collision: float = 50.0
    """Weight of the cubed ESDF penetration below the safe distance."""
    w_feasibility: float = 1.0
    """Weight of the squared speed / acceleration excess."""
    w_end: float = 10.0
    """Weight pulling the horizon's last control point to the guide path."""
    max_iterations: int = 100
    """L-BFGS iterations per optimisation (C++, GIL released)."""
    retries: int = 2
    """A curve ending at rest at the goal that fails its certification (collision or altitude) is optimised again
    from the same guide with half the control-point spacing, up to this many times: a slower curve with more
    freedom, which can bend round a corner the guide takes at the radius (e.g. a short leg between two offset
    tunnel frames, where the first spacing gives too few control points for a rest-to-rest move within the
    acceleration limit). A receding-horizon curve is not retried (its caller keeps the previous trajectory)."""
    z_min: float = 0.5
    """Lowest height of the flight band [m, world z]: the guide A* searches only in the band, its path is kept in
    it, and a trajectory leaving it (below the lower of z_min and its start or goal) is rejected ("altitude"). Unobserved ground is free space to
    the map: without the band a guide may dip into it (forest seed 0 on the LIO flew into the ground so)."""
    z_max: float = 3.0
    """Highest height of the flight band [m, world z]."""

    def __post_init__(self) -> None:
        for name in (
            "radius",
            "margin",
            "v_max",
            "a_max",
            "dt",
            "horizon",
            "w_smooth",
            "w_collision",
            "w_feasibility",
            "w_end",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and float(v) > 0):
                raise ConfigError(f"{name} must be a finite number > 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if (
            isinstance(self.max_iterations, bool)
            or not isinstance(self.max_iterations, numbers.Integral)
            or self.max_iterations < 1
        ):
            raise ConfigError(f"max_iterations must be an integer >= 1, got {self.max_iterations!r}")
        if (
            isinstance(self.retries, bool)
            or not isinstance(self.retries, numbers.Integral)
            or not 0 <= self.retries <= 8
        ):
            raise ConfigError(f"retries must be an integer in 0..8, got {self.retries!r}")
        for name in ("z_min", "z_max"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise ConfigError(f"{name} must be a finite number [m], got {v!r}")
            object.__setattr__(self, name, float(v))
        if not self.z_max > self.z_min:
            raise ConfigError(f"z_max must be > z_min, got z_min={self.z_min}, z_max={self.z_max}")


@dataclass(frozen=True)
class LocalPlan:
    """One replan's outcome."""

    status: str
    """"ok", "collision" (the optimised curve is closer than the radius somewhere), "altitude" (it leaves the
    flight band by more than 5 cm), "at_goal"."""
    trajectory: UniformBspline | None
    """The new trajectory from ``t`` (None unless ok)."""
    plan_seconds: float
    """Wall time of the replan [s]."""
    min_clearance: float
    """Smallest certified clearance along the curve [m] (inf for at_goal)."""
    path_length: float
    """Length of the new trajectory's curve [m] (0 unless ok)."""
    reaches_goal: bool = False
    """The trajectory ends at rest at the goal."""
    plan_cpu_seconds: float = 0.0
    """CPU time of the replan on its thread [s] (the wall time less any preemption by other processes)."""


class BsplineLocalPlanner:
    """Replans a B-spline on a (growing) :class:`~cufund.mapping.EsdfMap` from the current state to ``goal_W``."""

    def __init__(self, esdf_map: EsdfMap, params: LocalPlannerParams | None = None) -> None:
        if not isinstance(esdf_map, EsdfMap):
            raise TypeError(f"esdf_map must be a cufund.mapping.EsdfMap, got {type(esdf_map).__name__}")
        self.params = LocalPlannerParams() if params is None else params
        if not isinstance(self.params, LocalPlannerParams):
            raise TypeError(f"params must be a LocalPlannerParams, got {type(params).__name__}")
        self.esdf_map = esdf_map
        self.query = ClearanceQuery(esdf_map)
        # The guide only seeds the optimiser: weighted A* (w = 2: about half the expansions of 1.5 in forests,
        # the same length after shortcutting) with a bounded search (a few ms at most).
        self._guide = GridPathSearch(
            GridPathSearchParams(
                radius=self.params.radius,
                max_expansions=20_000,
                heuristic_weight=2.0,
                z_min=self.params.z_min,
                z_max=self.params.z_max,
            )
        )
        self._cache: tuple[np.ndarray, np.ndarray] | None = None  # (goal, guide path) of the last A*
        self._d_safe = self.params.radius + self.params.margin + 0.5 * math.sqrt(3.0) * esdf_map.params.resolution

    def replan(
        self,
        t: float,
        p_W: npt.ArrayLike,
        v_W: npt.ArrayLike,
        a_W: npt.ArrayLike,
        goal_W: npt.ArrayLike,
        yaw: float = 0.0,
    ) -> LocalPlan:
        """A trajectory from time ``t`` [s] and state (p, v, a) towards ``goal_W`` (3,) [m]."""
        t0, c0 = time.perf_counter(), time.thread_time()
        par = self.params
        p, v, a, goal = (np.asarray(x, dtype=float).reshape(3) for x in (p_W, v_W, a_W, goal_W))
        if np.linalg.norm(goal - p) < 0.05 and np.linalg.norm(v) < 0.05:
            return LocalPlan("at_goal", None, time.perf_counter() - t0, math.inf, 0.0, True, time.thread_time() - c0)
        path = self._guide_path(p, goal)
        fixed = start_control_points(p, v, a, par.dt)
        lo, hi = min(par.z_min, p[2], goal[2]), max(par.z_max, p[2], goal[2])
        for attempt in range(par.retries + 1):
            status, traj, clearance, length, reaches = self._attempt(
                path, fixed, goal, lo, hi, 0.5**attempt, float(t), float(yaw)
            )
            if status == "ok" or not reaches:  # only a curve that must stop at the goal is retried
                break
        return LocalPlan(
            status,
            traj,
            time.perf_counter() - t0,
            clearance,
            length,
            reaches and status == "ok",
            time.thread_time() - c0,
        )

    def _attempt(
        self,
        path: np.ndarray,
        fixed: np.ndarray,
        goal: np.ndarray,
        lo: float,
        hi: float,
        spacing: float,
        t: float,
        yaw: float,
    ) -> tuple[str, UniformBspline | None, float, float, bool]:
        """One optimisation along ``path`` with the control-point spacing scaled by ``spacing``, from time ``t``,
        certified: (status, trajectory or None, clearance, length, reaches the goal)."""
        par = self.params
        ds = spacing * 0.7 * par.v_max * par.dt
        pts, reaches = _resample(path, ds, par.horizon)
        pts[:, 2] = np.clip(pts[:, 2], lo, hi)  # the flight band (the goal and start may lie outside it)
        n_free = max(1, len(pts) - (0 if not reaches else 1))
        init = pts[:n_free]
        end_target = pts[-1]
        tail = np.repeat(goal[None], 3, axis=0) if reaches else np.zeros((0, 3))
        x = self._optimise(fixed, init, tail, end_target, reaches)
        q = np.vstack([fixed, x.reshape(-1, 3), tail])
        traj = UniformBspline(q, par.dt, t_start=t, yaw=yaw)
        ts = np.linspace(traj.t_start, traj.t_end, max(2, int(traj.duration / 0.01) + 1))
        curve = traj.sample(ts).p_W
        clearance = float(np.min(self.query.clearance(curve)))
        if curve[:, 2].min() < lo - 0.05 or curve[:, 2].max() > hi + 0.05:
            return "altitude", None, clearance, 0.0, reaches
        # Certified between the samples too: every chord of the 10 ms polyline is traced (the curve is
        # within a_max * (10 ms)^2 / 8 < 0.1 mm of its chords).
        if clearance < par.radius or not self.query.path_free(curve, par.radius).all():
            return "collision", None, clearance, 0.0, reaches
        length = float(np.sum(np.linalg.norm(np.diff(curve, axis=0), axis=1)))
        return "ok", traj, clearance, length, reaches

    def set_guide(self, goal_W: npt.ArrayLike, path_W: npt.ArrayLike) -> None:
        """Follow the polyline ``path_W`` (K, 3) [m] (e.g. a global plan) towards ``goal_W`` while its next
        horizon stays certified free on the map; a new grid A* only where it does not."""
        goal = np.asarray(goal_W, dtype=float).reshape(3)
        path = np.asarray(path_W, dtype=float)
        if path.ndim != 2 or path.shape[1] != 3 or path.shape[0] < 2 or not np.all(np.isfinite(path)):
            raise ValueError(f"path_W must be finite with shape (K, 3), K >= 2, got {path.shape}")
        self._cache = (goal.copy(), path.copy())

    def _guide_path(self, p: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """The last guide path from the point nearest ``p`` on, while its next ``horizon`` metres stay
        certified free on the current map; otherwise a new grid A* (a straight line if that fails)."""
        par = self.params
        if self._cache is not None and np.array_equal(self._cache[0], goal):
            g = self._cache[1]
            a, b = g[:-1], g[1:]
            ab = b - a
            u = np.clip(np.einsum("kd,kd->k", p - a, ab) / np.maximum(np.einsum("kd,kd->k", ab, ab), 1e-12), 0, 1)
            k = int(np.argmin(np.linalg.norm(a + u[:, None] * ab - p, axis=1)))
            cand = np.vstack([p, g[k + 1 :]])
            within = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(cand, axis=0), axis=1))])
            n = int(np.searchsorted(within, par.horizon)) + 1
            if self.query.path_free(cand[: n + 1], par.radius).all():
                return cand
        guide = self._guide.plan(self.query, p, goal)
        if not guide.found:
            self._cache = None
            return np.stack([p, goal])
        self._cache = (goal.copy(), guide.path_W)
        return guide.path_W

    def _optimise(
        self, fixed: np.ndarray, init: np.ndarray, tail: np.ndarray, end_target: np.ndarray, reaches: bool
    ) -> np.ndarray:
        par = self.params
        r = _core.planning.optimize_bspline(
            self.esdf_map._core,
            fixed,
            init,
            tail,
            end_target,
            not reaches,
            par.w_smooth,
            par.w_collision,
            par.w_feasibility,
            par.w_end,
            self._d_safe,
            par.v_max,
            par.a_max,
            par.dt,
            int(par.max_iterations),
        )
        return r["free"]


def _resample(path: np.ndarray, ds: float, horizon: float) -> tuple[np.ndarray, bool]:
    """Points every ``ds`` along the polyline after its start, up to ``horizon``; whether its end was reached
    (then the last point is the end)."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(cum[-1])
    reaches = total <= horizon
    stop = min(total, horizon)
    n = max(1, math.ceil(stop / ds))
    s = np.arange(1, n + 1) * (stop / n)
    out = np.stack([np.interp(s, cum, path[:, k]) for k in range(3)], axis=1)
    return out, reaches

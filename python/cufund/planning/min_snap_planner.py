"""Collision-free minimum-snap trajectories through a path: optimised times, waypoints inserted where the
trajectory leaves the path's corridor or comes too close to obstacles (Richter, Bry & Roy 2016).

The path (from :class:`GridPathSearch` or :class:`OmplPathPlanner`) is a polyline whose edges are free.
A min-snap spline through its vertices may cut corners or bulge; wherever a sampled point of the spline
is closer than ``radius`` to an obstacle (certified ESDF clearance) or farther than ``corridor`` from
the polyline, the polyline edge it belongs to is split at its midpoint and the spline recomputed. As
edges shrink the spline converges to the polyline, so the loop ends when the polyline clears the
radius by a margin (plan the path with ``radius + margin``).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cufund.core.config import ConfigError

from .clearance import ClearanceQuery
from .feasibility import TrajectoryFeasibility, feasibility
from .minimum_snap import MinimumSnapTrajectory

__all__ = ["MinSnapPlanner", "MinSnapPlannerParams", "MinSnapResult", "polyline_distance"]


def _positive(name: str, v: object, allow_none: bool = False) -> float | None:
    if v is None and allow_none:
        return None
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and float(v) > 0):
        raise ConfigError(f"{name} must be a finite number > 0, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class MinSnapPlannerParams:
    """Parameters of :class:`MinSnapPlanner`."""

    v_max: float = 1.0
    """Speed limit [m/s]: times are scaled so that the peak speed or acceleration meets its limit."""
    a_max: float = 2.0
    """Acceleration limit [m/s^2]."""
    optimize_times: bool = True
    """Redistribute segment times to minimise snap (Mellinger & Kumar) before scaling to the limits."""
    radius: float | None = None
    """Clearance [m] to keep from obstacles (needs a ClearanceQuery); None: not checked."""
    corridor: float | None = None
    """Half-width [m] of the tube around the waypoint polyline the trajectory must stay in; None: none."""
    sample_dt: float = 0.01
    """Spacing [s] of the samples checked against ``radius`` and ``corridor``."""
    max_waypoints: int = 400
    """Stop inserting (status "not_converged") beyond this many waypoints."""

    def __post_init__(self) -> None:
        for name in ("v_max", "a_max", "sample_dt"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        for name in ("radius", "corridor"):
            object.__setattr__(self, name, _positive(name, getattr(self, name), allow_none=True))
        if not isinstance(self.optimize_times, (bool, np.bool_)):
            raise ConfigError(f"optimize_times must be a bool, got {self.optimize_times!r}")
        if (
            isinstance(self.max_waypoints, bool)
            or not isinstance(self.max_waypoints, numbers.Integral)
            or self.max_waypoints < 2
        ):
            raise ConfigError(f"max_waypoints must be an integer >= 2, got {self.max_waypoints!r}")


@dataclass(frozen=True)
class MinSnapResult:
    """A trajectory and how it came about."""

    status: str
    """"ok" (every check passed) or "not_converged" (``max_waypoints`` reached; the last trajectory)."""
    trajectory: MinimumSnapTrajectory
    feasibility: TrajectoryFeasibility
    inserted: int
    """Waypoints inserted on the polyline."""
    min_clearance: float
    """Smallest certified clearance [m] over the samples (inf without a ClearanceQuery)."""
    max_corridor_error: float
    """Largest distance [m] of a sample from the waypoint polyline."""


def polyline_distance(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Distance [m] from each of ``points`` (N, 3) to the polyline (K, 3), K >= 2."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    L2 = np.maximum(np.einsum("kd,kd->k", ab, ab), 1e-300)
    best = np.full(points.shape[0], np.inf)
    for k in range(ab.shape[0]):  # K is small (tens); N may be large
        r = points - a[k]
        u = np.clip(r @ ab[k] / L2[k], 0.0, 1.0)
        r -= u[:, None] * ab[k]
        np.minimum(best, np.einsum("nd,nd->n", r, r), out=best)  # squared distances
    return np.sqrt(best)


class MinSnapPlanner:
    """Min-snap through a free polyline, with optimised times and waypoint insertion until it is safe."""

    def __init__(self, params: MinSnapPlannerParams | None = None) -> None:
        self.params = MinSnapPlannerParams() if params is None else params
        if not isinstance(self.params, MinSnapPlannerParams):
            raise TypeError(f"params must be a MinSnapPlannerParams, got {type(params).__name__}")

    def plan(
        self,
        waypoints_W: npt.ArrayLike,
        yaw: npt.ArrayLike | None = None,
        query: ClearanceQuery | None = None,
        t_start: float = 0.0,
    ) -> MinSnapResult:
        """The trajectory through ``waypoints_W`` (K, 3) [m] (yaw (K,) [rad] optional) from ``t_start`` [s]."""
        p = self.params
        w = np.asarray(waypoints_W, dtype=float)
        if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 2 or not np.all(np.isfinite(w)):
            raise ValueError(f"waypoints_W must be finite with shape (K, 3), K >= 2, got {w.shape}")
        if p.radius is not None and not isinstance(query, ClearanceQuery):
            raise ValueError("params.radius needs a ClearanceQuery (query=...)")
        psi = np.zeros(w.shape[0]) if yaw is None else np.unwrap(np.asarray(yaw, dtype=float))
        if psi.shape != (w.shape[0],):
            raise ValueError(f"yaw must have shape ({w.shape[0]},), got {psi.shape}")
        polyline = w.copy()
        inserted = 0
        while True:
            traj = MinimumSnapTrajectory(
                w, psi, v_max=p.v_max, a_max=p.a_max, t_start=t_start, optimize_times=p.optimize_times
            )
            bad, min_clear, corridor_err = self._violations(traj, polyline, query)
            if not bad.any() or w.shape[0] + int(bad.sum()) > p.max_waypoints:
                status = "ok" if not bad.any() else "not_converged"
                return MinSnapResult(
                    status=status,
                    trajectory=traj,
                    feasibility=feasibility(traj),
                    inserted=inserted,
                    min_clearance=min_clear,
                    max_corridor_error=corridor_err,
                )
            # Split every offending segment at its midpoint (position and yaw); the polyline is unchanged.
            seg = np.flatnonzero(bad)
            w = np.insert(w, seg + 1, 0.5 * (w[seg] + w[seg + 1]), axis=0)
            psi = np.insert(psi, seg + 1, 0.5 * (psi[seg] + psi[seg + 1]))
            inserted += seg.size

    def _violations(
        self, traj: MinimumSnapTrajectory, polyline: np.ndarray, query: ClearanceQuery | None
    ) -> tuple[np.ndarray, float, float]:
        """Per segment of ``traj``: does a sample break the clearance or the corridor?"""
        p = self.params
        n = max(2, math.ceil(traj.duration / p.sample_dt) + 1)
        t = np.linspace(traj.t_knots[0], traj.t_end, n)
        x = traj.sample(t).p_W
        seg = np.clip(np.searchsorted(traj.t_knots, t, side="right") - 1, 0, len(traj.durations) - 1)
        bad_sample = np.zeros(n, dtype=bool)
        min_clear = math.inf
        if query is not None:
            c = query.clearance(x)
            min_clear = float(np.min(c))
            if p.radius is not None:  # the samples and the chords between them (certified)
                bad_sample |= c < p.radius
                bad_sample[:-1] |= ~query.path_free(x, p.radius)
        err = polyline_distance(x, polyline)
        if p.corridor is not None:
            bad_sample |= err > p.corridor
        bad = np.zeros(len(traj.durations), dtype=bool)
        bad[seg[bad_sample]] = True
        return bad, min_clear, float(err.max())

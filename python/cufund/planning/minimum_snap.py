"""Minimum-snap trajectories through waypoints (paper §3.1, eq. 6; Mellinger & Kumar 2011).

Position minimises the integral of the squared 4th derivative (n = 4), yaw the squared 2nd derivative (m = 2),
each between fixed waypoints, starting and ending at rest (derivatives 1..n-1 zero at both ends).

The optimum of ``min sum_i int |p^(k)|^2 dt`` with fixed interior waypoints is, by the Euler-Lagrange equation
``p^(2k) = 0``, a piecewise polynomial of degree 2k-1 that is continuous to derivative 2k-2 at every interior
waypoint. Those conditions give exactly as many linear equations as coefficients, so the trajectory is the
solution of one banded linear system (no QP): a degree-7 spline continuous to the 6th derivative for position
(snap is continuous, as required), a cubic C^2 spline for yaw.
"""

from __future__ import annotations

import bisect
import functools
import math

import numpy as np

from cufund import _core

from .trajectory import TrajectorySamples

__all__ = [
    "MinimumSnapTrajectory",
    "allocate_segment_times",
    "min_derivative_spline",
    "optimize_segment_times",
    "snap_cost_and_gradient",
]

_POWERS8 = np.arange(8.0)


def min_derivative_spline(values: np.ndarray, durations: np.ndarray, order: int) -> np.ndarray:
    """Coefficients of the piecewise polynomial through ``values`` minimising ``int |p^(order)|^2 dt``.

    ``values`` (M+1, d) waypoints, ``durations`` (M,) segment times [s] > 0. Derivatives 1..order-1 are zero at
    both ends. Returns ``c`` of shape (M, 2*order, d) in normalised time: on segment i,
    ``p(t) = sum_j c[i, j] * s**j`` with ``s = (t - t_i) / durations[i]`` in [0, 1].
    The banded system is solved in C++ (``cufund._core.planning.min_derivative_spline``, partial pivoting).
    """
    return _core.planning.min_derivative_spline(
        np.asarray(values, dtype=float), np.asarray(durations, dtype=float), int(order)
    )


def allocate_segment_times(waypoints: np.ndarray, v_max: float, a_max: float) -> np.ndarray:
    """Rest-to-rest trapezoidal-profile time for each segment's straight-line distance [s]."""
    d = np.linalg.norm(np.diff(np.asarray(waypoints, dtype=float), axis=0), axis=1)
    tri = d < v_max * v_max / a_max
    return np.where(tri, 2.0 * np.sqrt(d / a_max), d / v_max + v_max / a_max)


def snap_cost_and_gradient(waypoints: np.ndarray, durations: np.ndarray) -> tuple[float, np.ndarray]:
    """Snap cost J [m^2/s^7] of the minimum-snap spline and its exact gradient dJ/dT_i.

    The Lagrangian |p^(4)|^2 has no explicit time, so the "energy" H = |p^(4)|^2 - 2 p^(1).p^(7)
    + 2 p^(2).p^(6) - 2 p^(3).p^(5) is constant on each segment of the optimum, and moving a knot changes
    the optimal cost by the jump of H there; summed over the knots after segment i (the end's fixed
    derivatives make its term -H), ``dJ/dT_i = -H_i``: one spline solve gives the whole gradient.
    Computed in C++ (``cufund._core.planning.snap_cost_and_gradient``).
    """
    J, g = _core.planning.snap_cost_and_gradient(np.asarray(waypoints, dtype=float), np.asarray(durations, dtype=float))
    return float(J), g


def optimize_segment_times(waypoints: np.ndarray, durations: np.ndarray, max_iterations: int = 100) -> np.ndarray:
    """Segment times with the same total as ``durations`` that minimise the snap cost (Mellinger & Kumar 2011).

    The snap cost is homogeneous in the times, ``J(a T) = a^-7 J(T)``, so the best allocation for a fixed
    total is the minimiser of the scale-free ``log J(T) + 7 log sum(T)``; it is found by BFGS over ``log T``
    with the exact gradient of :func:`snap_cost_and_gradient`, from ``durations``, and never returned worse.
    It runs in C++ (``cufund._core.planning.optimize_segment_times``: BFGS with a backtracking Armijo line search,
    the first inverse-Hessian estimate scaled to the first step's curvature) and stops when the gradient of that
    log-objective is below 1e-6 (infinity norm) or after ``max_iterations``.
    """
    w = np.asarray(waypoints, dtype=float)
    if w.ndim != 2 or w.shape[0] < 2:
        raise ValueError(f"waypoints must have shape (K, d) with K >= 2, got {w.shape}")
    # the durations (K - 1 finite times > 0) and the waypoints' values are checked by the binding
    return _core.planning.optimize_segment_times(w, durations, int(max_iterations), 1e-6)["durations"]


class MinimumSnapTrajectory:
    """Minimum-snap position (n = 4) and minimum-acceleration yaw (m = 2) through waypoints, from rest to rest.

    Args:
        waypoints_W: (K, 3) positions [m], K >= 2, consecutive ones distinct.
        yaw: (K,) yaw at each waypoint [rad] (unwrapped so each change is the shorter way round); zeros if None.
        durations: (K-1,) segment times [s]. If None they are allocated from ``v_max`` and ``a_max``: trapezoidal
            estimates per segment, then all scaled by one factor so the peak speed or acceleration of the
            resulting trajectory just meets its limit (a uniform time scaling keeps the optimal shape).
        v_max: speed limit for time allocation [m/s].
        a_max: acceleration limit for time allocation [m/s^2].
        t_start: time of the first waypoint [s].
        optimize_times: with ``durations`` None, redistribute the allocated times to minimise the snap cost
            (:func:`optimize_segment_times`) before the scaling to the limits.
    """

    def __init__(
        self,
        waypoints_W: np.ndarray,
        yaw: np.ndarray | None = None,
        durations: np.ndarray | None = None,
        v_max: float = 1.0,
        a_max: float = 2.0,
        t_start: float = 0.0,
        optimize_times: bool = False,
    ) -> None:
        w = np.asarray(waypoints_W, dtype=float)
        if w.ndim != 2 or w.shape[1] != 3 or w.shape[0] < 2:
            raise ValueError(f"waypoints_W must have shape (K, 3) with K >= 2, got {w.shape}")
        if not np.all(np.isfinite(w)):
            raise ValueError("waypoints_W must be finite")
        k = w.shape[0]
        psi = np.zeros(k) if yaw is None else np.asarray(yaw, dtype=float)
        if psi.shape != (k,) or not np.all(np.isfinite(psi)):
            raise ValueError(f"yaw must be {k} finite angles (one per waypoint), got shape {psi.shape}")
        psi = np.unwrap(psi)
        if durations is None:
            if not (v_max > 0 and a_max > 0):
                raise ValueError(f"v_max and a_max must be > 0, got {v_max}, {a_max}")
            if np.any(np.linalg.norm(np.diff(w, axis=0), axis=1) <= 0):
                raise ValueError("consecutive waypoints_W must differ to allocate segment times")
            T = allocate_segment_times(w, v_max, a_max)
            if optimize_times:
                T = optimize_segment_times(w, T)
        else:
            T = np.asarray(durations, dtype=float)
            if T.shape != (k - 1,) or not np.all(np.isfinite(T)) or np.any(T <= 0):
                raise ValueError(f"durations must be {k - 1} finite times > 0 [s], got {T}")
        self.waypoints_W = w
        self.yaw_waypoints = psi
        self.t_start = float(t_start)
        self._set_times(T)
        if durations is None:
            s = self.sample(self._dense_times())
            scale = max(
                np.max(np.linalg.norm(s.v_W, axis=1)) / v_max, math.sqrt(np.max(np.linalg.norm(s.a_W, axis=1)) / a_max)
            )
            self._set_times(T * scale)

    def _set_times(self, T: np.ndarray) -> None:
        self.durations = T
        self.t_knots = self.t_start + np.concatenate([[0.0], np.cumsum(T)])
        self.coeffs = min_derivative_spline(self.waypoints_W, T, 4)  # (M, 8, 3)
        self.yaw_coeffs = min_derivative_spline(self.yaw_waypoints[:, None], T, 2)  # (M, 4, 1)
        self._knots_list = self.t_knots.tolist()
        # The derivative tables, one form: per segment and derivative order r, the coefficients of the r-th time
        # derivative in powers of s, (M, 8, 8, 3) for position and (M, 4, 4, 1) for yaw, each segment's block
        # contiguous so that a sample's derivatives 0..3 (or 0..1) are one product (8,) @ (4, 8, 3).
        self._pos_tables = np.ascontiguousarray(_derivative_tables(self.coeffs, T).transpose(1, 0, 2, 3))
        self._yaw_tables = np.ascontiguousarray(_derivative_tables(self.yaw_coeffs, T).transpose(1, 0, 2, 3))

    def _dense_times(self, per_segment: int = 16) -> np.ndarray:
        s = np.linspace(0.0, 1.0, per_segment, endpoint=False)
        return (self.t_knots[:-1, None] + self.durations[:, None] * s).ravel()

    @property
    def duration(self) -> float:
        """Total time [s]."""
        return float(self.t_knots[-1] - self.t_knots[0])

    @property
    def t_end(self) -> float:
        """Time of the last waypoint [s]."""
        return float(self.t_knots[-1])

    def derivative(self, t: np.ndarray | float, r: int, which: str = "position") -> np.ndarray:
        """The r-th time derivative at times ``t``: (N, 3) for position, (N,) for yaw; rest outside the span."""
        tables = self._pos_tables if which == "position" else self._yaw_tables
        if which not in ("position", "yaw") or not 0 <= r < tables.shape[1]:
            raise ValueError(
                f"r must be a derivative order in 0..7 for position or 0..3 for yaw, got {r} for {which!r}"
            )
        tab = tables[:, r]  # (M, nc, d)
        t = np.atleast_1d(np.asarray(t, dtype=float))
        i, s = self._locate(t)
        c = tab[i]  # (N, nc, d)
        out = c[:, -1]
        for p in range(c.shape[1] - 2, -1, -1):  # Horner
            out = out * s[:, None] + c[:, p]
        if r > 0:
            out = np.where(((t < self.t_knots[0]) | (t > self.t_knots[-1]))[:, None], 0.0, out)
        return out if which == "position" else out[:, 0]

    def _locate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i = np.clip(np.searchsorted(self.t_knots, t, side="right") - 1, 0, len(self.durations) - 1)
        return i, np.clip((t - self.t_knots[i]) / self.durations[i], 0.0, 1.0)

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        if isinstance(t, (float, int)):
            return self._sample_one(float(t))
        t = np.atleast_1d(np.asarray(t, dtype=float))
        i, s = self._locate(t)
        inside = ((t >= self.t_knots[0]) & (t <= self.t_knots[-1]))[:, None]
        S = np.vander(s, 8, increasing=True)  # powers of s, (N, 8)
        # Per segment the tables' columns a sample takes side by side, (M, 8, 14): p, v, a, j (3 columns each), yaw,
        # yaw rate (the cubic's rows padded with zeros), so a run of samples in one segment is one matmul.
        m = len(self.durations)
        table = np.zeros((m, 8, 14))
        table[:, :, :12] = self._pos_tables[:, :4].transpose(0, 2, 1, 3).reshape(m, 8, 12)
        table[:, :4, 12:] = self._yaw_tables[:, :2, :, 0].transpose(0, 2, 1)
        out = np.empty((t.size, 14))
        if t.size > 1 and np.all(i[1:] >= i[:-1]):  # sorted times: one matmul per segment
            bounds = np.searchsorted(i, np.arange(m + 1))
            for k in np.flatnonzero(bounds[1:] > bounds[:-1]).tolist():
                np.matmul(S[bounds[k] : bounds[k + 1]], table[k], out=out[bounds[k] : bounds[k + 1]])
        else:
            np.einsum("nj,njc->nc", S, table[i], out=out)

        def rest(a: np.ndarray) -> np.ndarray:  # derivatives are zero outside the span
            return np.where(inside, a, 0.0)

        return TrajectorySamples(
            t=t,
            p_W=np.ascontiguousarray(out[:, 0:3]),
            v_W=rest(out[:, 3:6]),
            a_W=rest(out[:, 6:9]),
            j_W=rest(out[:, 9:12]),
            yaw=out[:, 12].copy(),
            yaw_rate=np.where(inside[:, 0], out[:, 13], 0.0),
        )

    def _sample_one(self, t: float) -> TrajectorySamples:
        """The same as :meth:`sample` for one time, without the vectorised machinery (for per-tick setpoints)."""
        knots = self._knots_list
        i = min(max(bisect.bisect_right(knots, t) - 1, 0), len(knots) - 2)
        s = min(max((t - knots[i]) / (knots[i + 1] - knots[i]), 0.0), 1.0)
        S = s**_POWERS8
        pos = S @ self._pos_tables[i, :4]  # (4, 3): position, velocity, acceleration, jerk
        yaw = S[:4] @ self._yaw_tables[i, :2]  # (2, 1): yaw, yaw rate
        if not knots[0] <= t <= knots[-1]:
            pos[1:] = 0.0
            yaw[1] = 0.0
        return TrajectorySamples(
            t=np.array([t]), p_W=pos[0:1], v_W=pos[1:2], a_W=pos[2:3], j_W=pos[3:4], yaw=yaw[0], yaw_rate=yaw[1]
        )

    def snap_cost(self) -> float:
        """``sum_i int |p''''(t)|^2 dt`` over all segments, exact [m^2/s^7] (:func:`snap_cost_and_gradient`)."""
        return snap_cost_and_gradient(self.waypoints_W, self.durations)[0]


def _derivative_tables(c: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Per derivative order r, the coefficients (M, nc, d) of p^(r) in powers of s, scaled to time units:
    (nc, M, nc, d), indexed by r."""
    nc = c.shape[1]
    src, factor = _derivative_gather(nc)
    T_r = np.stack([T**r for r in range(nc)])  # scalar powers (as sampled one by one)
    return c[:, src].transpose(1, 0, 2, 3) * factor[:, None, :, None] / T_r[:, :, None, None]


@functools.lru_cache(maxsize=8)
def _derivative_gather(nc: int) -> tuple[np.ndarray, np.ndarray]:
    """For the r-th derivative of sum_j c_j s^j = sum_p c_(p+r) (p+r)!/p! s^p: the source index p + r and the
    factor (p+r)!/p! (0 where p + r >= nc), each (nc, nc) indexed [r, p] (read-only)."""
    r, p = np.arange(nc)[:, None], np.arange(nc)[None, :]
    src = np.minimum(r + p, nc - 1)
    factor = np.array(
        [[math.factorial(a + b) / math.factorial(b) if a + b < nc else 0.0 for b in range(nc)] for a in range(nc)]
    )
    for a in (src, factor):
        a.flags.writeable = False
    return src, factor

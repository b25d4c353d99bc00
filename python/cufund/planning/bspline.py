"""Uniform cubic B-spline trajectories: C^2 (position, velocity, acceleration continuous), local control.

Segment k (k = 0 .. n-4) of a spline with control points Q_0..Q_{n-1} and knot interval dt spans
``t_start + [k, k+1] dt``; with ``u`` the fraction through it, ``p = [1 u u^2 u^3] M [Q_k .. Q_{k+3}]``.
A spline's velocity, acceleration and jerk control points are scaled differences of Q (convex hull:
the curve lies in the hull of each window of 4 control points).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .trajectory import TrajectorySamples

__all__ = ["UniformBspline", "start_control_points"]

_M = np.array([[1.0, 4.0, 1.0, 0.0], [-3.0, 0.0, 3.0, 0.0], [3.0, -6.0, 3.0, 0.0], [-1.0, 3.0, -3.0, 1.0]]) / 6.0


def start_control_points(p_W: npt.ArrayLike, v_W: npt.ArrayLike, a_W: npt.ArrayLike, dt: float) -> np.ndarray:
    """Q_0, Q_1, Q_2 (3, 3) that make the spline start at position ``p_W``, velocity ``v_W`` and
    acceleration ``a_W``: p = (Q0 + 4 Q1 + Q2)/6, v = (Q2 - Q0)/(2 dt), a = (Q0 - 2 Q1 + Q2)/dt^2."""
    p, v, a = (np.asarray(x, dtype=float) for x in (p_W, v_W, a_W))
    q1 = p - a * dt * dt / 6.0
    s = a * dt * dt + 2.0 * q1  # Q0 + Q2
    d = 2.0 * dt * v  # Q2 - Q0
    return np.stack([(s - d) / 2.0, q1, (s + d) / 2.0])


class UniformBspline:
    """A uniform cubic B-spline position trajectory with constant yaw; implements :class:`Trajectory`.

    Outside ``[t_start, t_start + duration]`` it holds the end positions at rest (as every
    :class:`Trajectory`); a spline that ends at rest (its last 3 control points equal) does so smoothly."""

    def __init__(self, control_points_W: npt.ArrayLike, dt: float, t_start: float = 0.0, yaw: float = 0.0) -> None:
        q = np.asarray(control_points_W, dtype=float)
        if q.ndim != 2 or q.shape[1] != 3 or q.shape[0] < 4 or not np.all(np.isfinite(q)):
            raise ValueError(f"control_points_W must be finite with shape (n, 3), n >= 4, got {q.shape}")
        if not (dt > 0 and np.isfinite(dt)):
            raise ValueError(f"dt must be finite and > 0 [s], got {dt!r}")
        self.control_points_W = q
        self.dt = float(dt)
        self.t_start = float(t_start)
        self.yaw = float(yaw)
        # (segments, 4 powers, 3) polynomial coefficients in u, per derivative order 0..3 (time units)
        win = np.stack([q[k : k + 4] for k in range(q.shape[0] - 3)])  # (S, 4, 3)
        c = np.einsum("pj,sjd->spd", _M, win)
        self._coef = [c]
        for _r in range(1, 4):
            prev = self._coef[-1]
            d = np.zeros_like(prev)
            d[:, :-1] = prev[:, 1:] * np.arange(1, 4)[None, :, None] / self.dt
            self._coef.append(d)

    @property
    def duration(self) -> float:
        return self.dt * (self.control_points_W.shape[0] - 3)

    @property
    def t_end(self) -> float:
        return self.t_start + self.duration

    def derivative(self, t: npt.ArrayLike, r: int) -> np.ndarray:
        """The r-th derivative (r = 0..3) at times ``t`` -> (N, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        x = np.clip((t - self.t_start) / self.dt, 0.0, self.control_points_W.shape[0] - 3)
        k = np.minimum(x.astype(int), self.control_points_W.shape[0] - 4)
        u = x - k
        c = self._coef[r][k]  # (N, 4, 3)
        out = ((c[:, 3] * u[:, None] + c[:, 2]) * u[:, None] + c[:, 1]) * u[:, None] + c[:, 0]
        if r > 0:
            out[(t < self.t_start) | (t > self.t_end)] = 0.0
        return out

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        ta = np.atleast_1d(np.asarray(t, dtype=float))
        d = [self.derivative(ta, r) for r in range(4)]
        n = ta.shape[0]
        return TrajectorySamples(
            t=ta, p_W=d[0], v_W=d[1], a_W=d[2], j_W=d[3], yaw=np.full(n, self.yaw), yaw_rate=np.zeros(n)
        )

"""Jerk-limited point-to-point moves (take-off, landing, go-to) computed by ruckig (Berscheid & Kroeger 2021)."""

from __future__ import annotations

import numpy as np

from .trajectory import TrajectorySamples

__all__ = ["JerkLimitedMove"]


class JerkLimitedMove:
    """Time-optimal move from ``start_W`` to ``goal_W`` [m], ending at rest, under per-axis limits on velocity
    [m/s], acceleration [m/s^2] and jerk [m/s^3], holding ``yaw`` [rad]; starts at ``t_start`` [s], at rest or
    with velocity ``start_v_W`` [m/s] and acceleration ``start_a_W`` [m/s^2] (re-targeting a moving reference).

    Position, velocity and acceleration come from ruckig; jerk (which ruckig's Python API does not return) is the
    central difference of its acceleration over 0.1 ms, exact inside each constant-jerk phase.
    """

    def __init__(
        self,
        start_W: np.ndarray,
        goal_W: np.ndarray,
        v_max: float = 1.0,
        a_max: float = 2.0,
        j_max: float = 5.0,
        yaw: float = 0.0,
        t_start: float = 0.0,
        start_v_W: np.ndarray | None = None,
        start_a_W: np.ndarray | None = None,
    ) -> None:
        from ruckig import InputParameter, Result, Ruckig, Trajectory

        points: list[np.ndarray] = []
        for name, x in (("start_W", start_W), ("goal_W", goal_W), ("start_v_W", start_v_W), ("start_a_W", start_a_W)):
            if x is None:
                points.append(np.zeros(3))
                continue
            try:
                p = np.asarray(x, dtype=float)
            except (TypeError, ValueError):
                p = np.full(1, np.nan)  # reported below
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"{name} must be 3 finite numbers [m], got {x!r}")
            points.append(p)
        a, b, v0, a0 = points
        for name, lim in (("v_max", v_max), ("a_max", a_max), ("j_max", j_max)):
            if (
                isinstance(lim, bool)
                or not isinstance(lim, (int, float, np.integer, np.floating))
                or not (np.isfinite(lim) and lim > 0)
            ):
                raise ValueError(f"{name} must be a finite number > 0, got {lim!r}")
        inp = InputParameter(3)
        inp.current_position, inp.target_position = a.tolist(), b.tolist()
        inp.current_velocity, inp.current_acceleration = v0.tolist(), a0.tolist()
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v_max] * 3, [a_max] * 3, [j_max] * 3
        self._traj = Trajectory(3)
        try:
            result = Ruckig(3).calculate(inp, self._traj)
        except Exception as e:  # RuckigError (e.g. a waypoint at 1.5e16 m) is not a ValueError
            raise ValueError(f"ruckig could not plan the move from start_W {a} to goal_W {b}: {e}") from None
        if result not in (Result.Working, Result.Finished):
            raise ValueError(f"ruckig could not plan the move from {a} to {b}: {result}")
        self.start_W, self.goal_W = a, b
        self.yaw_value = float(yaw)
        self.t_start = float(t_start)

    @property
    def duration(self) -> float:
        return float(self._traj.duration)

    @property
    def t_end(self) -> float:
        return self.t_start + self.duration

    def _acc(self, tau: float) -> np.ndarray:
        return np.asarray(self._traj.at_time(min(max(tau, 0.0), self.duration))[2])

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        n = t.shape[0]
        p, v, a, j = (np.zeros((n, 3)) for _ in range(4))
        h = 5e-5
        for k, tk in enumerate(t):
            tau = min(max(tk - self.t_start, 0.0), self.duration)
            pk, vk, ak = self._traj.at_time(tau)
            p[k], v[k], a[k] = pk, vk, ak
            if 0.0 < tk - self.t_start < self.duration:
                j[k] = (self._acc(tau + h) - self._acc(tau - h)) / (2 * h)
        return TrajectorySamples(t=t, p_W=p, v_W=v, a_W=a, j_W=j, yaw=np.full(n, self.yaw_value), yaw_rate=np.zeros(n))

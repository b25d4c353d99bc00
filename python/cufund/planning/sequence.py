"""Trajectories one after another (take-off, hover, a min-snap path, landing), and holding a point."""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from .trajectory import Trajectory, TrajectorySamples

__all__ = ["Hold", "TrajectorySequence"]


class Hold:
    """Stay at ``p_W`` [m] with heading ``yaw`` [rad] from ``t_start`` for ``duration`` [s]; with ``yaw_end``
    [rad], turn from ``yaw`` to it meanwhile (the shorter way) with a smooth (cosine) rate profile
    (:meth:`turn` sets the duration from a peak yaw rate)."""

    def __init__(
        self, p_W: np.ndarray, duration: float, yaw: float = 0.0, t_start: float = 0.0, yaw_end: float | None = None
    ) -> None:
        self.p_W = np.asarray(p_W, dtype=float)
        if self.p_W.shape != (3,) or not np.all(np.isfinite(self.p_W)):
            raise ValueError(f"p_W must be 3 finite numbers [m], got {p_W}")
        if not (np.isfinite(duration) and duration >= 0):
            raise ValueError(f"duration must be a finite number >= 0 [s], got {duration!r}")
        self._duration, self.yaw, self.t_start = float(duration), float(yaw), float(t_start)
        self.delta = 0.0 if yaw_end is None else _turn(self.yaw, float(yaw_end))
        """The turn [rad] (0: none)."""
        if self.delta != 0.0 and self._duration <= 0:
            raise ValueError(f"a turn needs duration > 0 [s], got {duration!r}")

    @classmethod
    def turn(cls, p_W: np.ndarray, yaw: float, yaw_end: float, yaw_rate: float, t_start: float = 0.0) -> Hold:
        """Hold ``p_W`` while the heading turns from ``yaw`` to ``yaw_end`` [rad] (the shorter way), the cosine
        rate profile peaking at ``yaw_rate`` [rad/s]."""
        if not (np.isfinite(yaw_rate) and yaw_rate > 0):
            raise ValueError(f"yaw_rate must be a finite number > 0 [rad/s], got {yaw_rate!r}")
        delta = _turn(float(yaw), float(yaw_end))
        return cls(p_W, max(math.pi * abs(delta) / (2 * yaw_rate), 1e-3), yaw, t_start, yaw_end=yaw_end)

    @property
    def duration(self) -> float:
        return self._duration

    @property
    def t_end(self) -> float:
        return self.t_start + self._duration

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        z = np.zeros((t.shape[0], 3))
        if self.delta == 0.0:
            yaw, yaw_rate = np.full(t.shape[0], self.yaw), np.zeros(t.shape[0])
        else:
            s = np.clip((t - self.t_start) / self._duration, 0.0, 1.0)
            yaw = self.yaw + self.delta * 0.5 * (1 - np.cos(np.pi * s))
            inside = (s > 0) & (s < 1)
            yaw_rate = np.where(inside, self.delta * 0.5 * np.pi * np.sin(np.pi * s) / self._duration, 0.0)
        return TrajectorySamples(
            t=t, p_W=np.tile(self.p_W, (t.shape[0], 1)), v_W=z, a_W=z.copy(), j_W=z.copy(), yaw=yaw, yaw_rate=yaw_rate
        )


def _turn(yaw: float, yaw_end: float) -> float:
    """The shorter turn from ``yaw`` to ``yaw_end`` [rad]; a ValueError naming them unless both are finite."""
    if not (math.isfinite(yaw) and math.isfinite(yaw_end)):
        raise ValueError(f"a turn's yaw and yaw_end must be finite angles [rad], got {yaw!r} and {yaw_end!r}")
    return math.remainder(yaw_end - yaw, 2 * math.pi)


class TrajectorySequence:
    """Parts with absolute start times (each part's ``t_start``), played in order; each time is served by the
    last part that has started (the first part before it starts)."""

    def __init__(self, parts: Sequence[Trajectory]) -> None:
        if not parts:
            raise ValueError("parts must hold at least one trajectory")
        starts = [float(p.t_start) for p in parts]
        if any(b < a for a, b in pairwise(starts)):
            raise ValueError(f"parts must start in time order, got start times {starts}")
        self.parts = list(parts)
        self._starts = np.array(starts)
        self._starts_list = starts
        self.t_start = starts[0]

    @property
    def duration(self) -> float:
        return self.t_end - self.t_start

    @property
    def t_end(self) -> float:
        last = self.parts[-1]
        return float(last.t_start + last.duration)

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        if isinstance(t, (float, int)):
            i = max(bisect.bisect_right(self._starts_list, t) - 1, 0)
            return self.parts[i].sample(t)
        t = np.atleast_1d(np.asarray(t, dtype=float))
        idx = np.clip(np.searchsorted(self._starts, t, side="right") - 1, 0, len(self.parts) - 1)
        if np.all(idx == idx[0]):
            return self.parts[idx[0]].sample(t)
        out = {k: np.zeros((t.shape[0], 3)) for k in ("p_W", "v_W", "a_W", "j_W")}
        yaw, yaw_rate = np.zeros(t.shape[0]), np.zeros(t.shape[0])
        for i in np.unique(idx):
            m = idx == i
            s = self.parts[i].sample(t[m])
            for k in out:
                out[k][m] = getattr(s, k)
            yaw[m], yaw_rate[m] = s.yaw, s.yaw_rate
        return TrajectorySamples(t=t, yaw=yaw, yaw_rate=yaw_rate, **out)

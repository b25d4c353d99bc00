"""What a commander flies for a mission started on the ground, leg by leg, as
:class:`~cufund.missions.commander.Commander` flies it: the take-off straight up to the first waypoint's height (at
least 0.5 m) at ``takeoff_speed``, a jerk-limited move from rest to each waypoint (``v_max``, ``a_max``, ``j_max``
per axis) and its ``hold_s`` there, then, for a return, the climb to ``rtl_altitude`` above home if lower, home,
down to ``land_alt`` at go-to speed and the final descent at ``land_speed``. The vehicle's tracking lag (a leg ends
once the vehicle is within ``acceptance_radius``) is not in it. Used to deconflict and to synchronise fleet
missions."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from cufund.planning.point_to_point import JerkLimitedMove

from .deconfliction import Trajectory
from .params import CommanderParams

__all__ = ["commander_trajectory", "item_arrivals"]


def _legs(
    home: np.ndarray, waypoints: np.ndarray, p: CommanderParams, return_home: bool, holds: np.ndarray
) -> list[tuple[np.ndarray, float, float, int]]:
    """(target, speed limit, hold after [s], item index or -1)."""
    first = waypoints[0]
    legs = [(np.array([home[0], home[1], max(first[2], home[2] + 0.5)]), p.takeoff_speed, 0.0, -1)]
    legs += [(np.asarray(w, dtype=float), p.v_max, float(holds[i]), i) for i, w in enumerate(waypoints)]
    if return_home:
        z = max(float(waypoints[-1][2]), home[2] + p.rtl_altitude)
        last = np.asarray(waypoints[-1], dtype=float)
        legs += [
            (np.array([last[0], last[1], z]), p.v_max, 0.0, -1),
            (np.array([home[0], home[1], z]), p.v_max, 0.0, -1),
            (np.array([home[0], home[1], home[2] + p.land_alt]), p.v_max, 0.0, -1),
        ]
    return legs


def item_arrivals(
    home: ArrayLike,
    waypoints: np.ndarray,
    params: CommanderParams | None = None,
    holds: ArrayLike | None = None,
) -> np.ndarray:
    """When the reference arrives at each waypoint [s after mission_start]."""
    p = params or CommanderParams()
    wp = np.asarray(waypoints, dtype=float).reshape(-1, 3)
    h = np.zeros(len(wp)) if holds is None else np.asarray(holds, dtype=float)
    t, at = 0.0, np.asarray(home, dtype=float)
    out = np.zeros(len(wp))
    for target, v, hold, i in _legs(at, wp, p, False, h):
        if np.linalg.norm(target - at) > 1e-9:
            t += JerkLimitedMove(at, target, v, p.a_max, p.j_max, 0.0).duration
        if i >= 0:
            out[i] = t
        t, at = t + hold, target
    return out


def commander_trajectory(
    home: ArrayLike,
    waypoints: np.ndarray,
    params: CommanderParams | None = None,
    return_home: bool = True,
    holds: ArrayLike | None = None,
    dt: float = 0.1,
) -> Trajectory:
    """The commander's reference for the mission (see the module doc), sampled every ``dt`` [s] from
    mission_start at t = 0; ``holds`` the waits at the waypoints [s] (default none)."""
    p = params or CommanderParams()
    wp = np.asarray(waypoints, dtype=float).reshape(-1, 3)
    h = np.zeros(len(wp)) if holds is None else np.asarray(holds, dtype=float)
    at = np.asarray(home, dtype=float)
    home_W = at.copy()
    ts, ps = [0.0], [at]
    t = 0.0
    for target, v, hold, _ in _legs(at, wp, p, return_home, h):
        if np.linalg.norm(target - at) > 1e-9:
            move = JerkLimitedMove(at, target, v, p.a_max, p.j_max, 0.0, t_start=t)
            k = np.arange(1, max(1, math.ceil(move.duration / dt)) + 1)
            tk = t + np.minimum(k * dt, move.duration)
            ts += list(tk)
            ps += list(move.sample(tk).p_W)
            t, at = t + move.duration, target
        if hold > 0:
            t += hold
            ts.append(t)
            ps.append(at)
    if return_home and at[2] > home_W[2]:  # the final descent at land_speed
        ts.append(t + (at[2] - home_W[2]) / p.land_speed)
        ps.append(home_W)
    return Trajectory(np.asarray(ts), np.asarray(ps))

"""Deconfliction of planned fleet trajectories, so that every pair keeps a minimum separation.

Two methods:

- :func:`time_shift` (priority-based): vehicles in priority order keep their paths; each later vehicle waits at its
  start for the shortest delay (a multiple of ``step``) after which its whole trajectory keeps ``min_separation``
  from every vehicle before it, waiting included. Checked exactly (:func:`min_separation`: trajectories are
  piecewise linear in time, so the closest approach on each common interval is a quadratic's minimum). It cannot
  solve two vehicles swapping places along one line (one waits where the other arrives): that is ORCA's case.
- :func:`orca` (reciprocal velocity obstacles): the vehicles fly their waypoints at once, each step every vehicle
  takes the velocity nearest its preferred one (towards its next waypoint) that keeps it out of each neighbour's
  velocity obstacle for ``time_horizon`` seconds, taking half of the avoidance (ORCA, van den Berg, Guy, Lin and
  Manocha, "Reciprocal n-body collision avoidance", ISRR 2009 / STAR 69, 2011), solved by the paper's linear
  programs (a port of RVO2's ``Agent::computeNewVelocity``, agents only). Planar: avoidance in x-y, each vehicle's
  height follows its own waypoints.

Written here, not taken from a library: ``rvo2`` and ``pyorca`` are not on PyPI, and its one RVO2 binding there
(``pyrvo2-danieldugas`` 0.0.2, 2020, an sdist) builds RVO2 with CMake during install and fails to build here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["OrcaResult", "Trajectory", "min_separation", "orca", "time_shift"]

_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A piecewise-linear trajectory: positions ``p`` ((K, 3), ENU [m]) at increasing times ``t`` ((K,) [s]); before
    ``t[0]`` and after ``t[-1]`` the vehicle rests at its first / last position."""

    t: np.ndarray
    p: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float).reshape(-1)
        p = np.asarray(self.p, dtype=float).reshape(len(t), -1)
        if len(t) == 0 or not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise ValueError("a trajectory needs at least one finite sample")
        if np.any(np.diff(t) < 0):
            raise ValueError("trajectory times must not decrease")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "p", p)

    @classmethod
    def from_path(cls, path: Sequence[Sequence[float]], speed: float, t0: float = 0.0) -> Trajectory:
        """The path's waypoints flown at constant ``speed`` [m/s] from ``t0`` [s]."""
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be a finite number > 0 [m/s], got {speed!r}")
        p = np.asarray(path, dtype=float)
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1) if len(p) > 1 else np.zeros(0)
        return cls(t0 + np.concatenate([[0.0], np.cumsum(seg)]) / speed, p)

    def shifted(self, delay: float) -> Trajectory:
        """The same trajectory started ``delay`` [s] later (resting at its start meanwhile)."""
        return Trajectory(self.t + delay, self.p)

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """Position(s) at time(s) ``t``."""
        tt = np.asarray(t, dtype=float)
        return np.stack([np.interp(tt, self.t, self.p[:, k]) for k in range(self.p.shape[1])], axis=-1)

    @property
    def t_end(self) -> float:
        return float(self.t[-1])


def min_separation(a: Trajectory, b: Trajectory) -> tuple[float, float]:
    """The smallest distance between ``a`` and ``b`` over all time and when it occurs ``(d [m], t [s])``, exact for
    piecewise-linear trajectories."""
    times = np.union1d(a.t, b.t)
    d = a.at(times) - b.at(times)  # the difference is linear between consecutive breakpoints
    best, when = float(np.linalg.norm(d[0])), float(times[0])
    for k in range(len(times) - 1):
        d0, d1 = d[k], d[k + 1]
        e = d1 - d0
        ee = float(e @ e)
        s = 0.0 if ee < _EPS * _EPS else min(1.0, max(0.0, -float(d0 @ e) / ee))
        dist = float(np.linalg.norm(d0 + s * e))
        if dist < best:
            best, when = dist, float(times[k] + s * (times[k + 1] - times[k]))
    return best, when


def time_shift(
    trajectories: Mapping[str, Trajectory],
    min_sep: float,
    priority: Sequence[str] | None = None,
    step: float = 0.5,
    max_delay: float = 600.0,
) -> dict[str, float]:
    """Start delays [s] per vehicle (see the module doc): the first vehicle of ``priority`` (default: the mapping's
    order) 0, each later one the smallest multiple of ``step`` that keeps it ``min_sep`` [m] from all earlier ones.
    ``ValueError`` when no delay up to ``max_delay`` does (naming the vehicles)."""
    if not (math.isfinite(min_sep) and min_sep >= 0):
        raise ValueError(f"min_sep must be a finite number >= 0 [m], got {min_sep!r}")
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be a finite number > 0 [s], got {step!r}")
    order = list(trajectories) if priority is None else list(priority)
    if sorted(order) != sorted(trajectories):
        raise ValueError(f"priority must list each vehicle once: {sorted(trajectories)}, got {order}")
    delays: dict[str, float] = {}
    placed: list[tuple[str, Trajectory]] = []
    for name in order:
        traj = trajectories[name]
        k = 0
        while True:
            delay = k * step
            if delay > max_delay:
                blockers = [o for o, other in placed if min_separation(traj.shifted(max_delay), other)[0] < min_sep]
                raise ValueError(
                    f"{name} keeps no {min_sep} m separation from {', '.join(blockers)} with any start delay up to "
                    f"{max_delay} s"
                )
            moved = traj.shifted(delay)
            if all(min_separation(moved, other)[0] >= min_sep for _, other in placed):
                break
            k += 1
        delays[name] = delay
        placed.append((name, traj.shifted(delay)))
    return delays


# -- ORCA ------------------------------------------------------------------------------------------------------------


def _det(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _lp1(lines: list[tuple[np.ndarray, np.ndarray]], no: int, radius: float, opt: np.ndarray, direction_opt: bool
         ) -> np.ndarray | None:  # fmt: skip
    point, direction = lines[no]
    dot = float(point @ direction)
    disc = dot * dot + radius * radius - float(point @ point)
    if disc < 0:
        return None  # the speed disc misses this line
    sq = math.sqrt(disc)
    t_left, t_right = -dot - sq, -dot + sq
    for i in range(no):
        p_i, d_i = lines[i]
        den = _det(direction, d_i)
        num = _det(d_i, point - p_i)
        if abs(den) <= _EPS:
            if num < 0:
                return None  # parallel and on the wrong side
            continue
        t = num / den
        if den >= 0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        t = t_right if float(opt @ direction) > 0 else t_left
    else:
        t = min(max(float(direction @ (opt - point)), t_left), t_right)
    return point + t * direction


def _lp2(lines: list[tuple[np.ndarray, np.ndarray]], radius: float, opt: np.ndarray, direction_opt: bool
         ) -> tuple[int, np.ndarray]:  # fmt: skip
    if direction_opt:
        result = opt * radius
    elif float(opt @ opt) > radius * radius:
        result = opt / np.linalg.norm(opt) * radius
    else:
        result = opt.copy()
    for i, (p, d) in enumerate(lines):
        if _det(d, p - result) > 0:  # the result violates line i
            new = _lp1(lines, i, radius, opt, direction_opt)
            if new is None:
                return i, result
            result = new
    return len(lines), result


def _lp3(lines: list[tuple[np.ndarray, np.ndarray]], begin: int, radius: float, result: np.ndarray) -> np.ndarray:
    distance = 0.0
    for i in range(begin, len(lines)):
        p_i, d_i = lines[i]
        if _det(d_i, p_i - result) > distance:  # minimise the largest violation
            proj: list[tuple[np.ndarray, np.ndarray]] = []
            for j in range(i):
                p_j, d_j = lines[j]
                den = _det(d_i, d_j)
                if abs(den) <= _EPS:
                    if float(d_i @ d_j) > 0:
                        continue
                    point = 0.5 * (p_i + p_j)
                else:
                    point = p_i + (_det(d_j, p_i - p_j) / den) * d_i
                direction = d_j - d_i
                proj.append((point, direction / np.linalg.norm(direction)))
            fail, new = _lp2(proj, radius, np.array([-d_i[1], d_i[0]]), True)
            if fail == len(proj):
                result = new
            distance = _det(d_i, p_i - result)
    return result


def orca_velocity(
    p: np.ndarray,
    v: np.ndarray,
    v_pref: np.ndarray,
    others_p: Sequence[np.ndarray],
    others_v: Sequence[np.ndarray],
    radius: float,
    max_speed: float,
    time_horizon: float,
    dt: float,
) -> np.ndarray:
    """One agent's new planar velocity (2,) [m/s] among neighbours of the same ``radius`` (ORCA, RVO2's
    ``computeNewVelocity``)."""
    lines: list[tuple[np.ndarray, np.ndarray]] = []
    inv_tau = 1.0 / time_horizon
    r = 2.0 * radius
    for q, vq in zip(others_p, others_v, strict=True):
        rel_p = q - p
        rel_v = v - vq
        dist_sq = float(rel_p @ rel_p)
        if dist_sq > r * r:
            w = rel_v - inv_tau * rel_p
            w_sq = float(w @ w)
            dot1 = float(w @ rel_p)
            if dot1 < 0 and dot1 * dot1 > r * r * w_sq:  # project on the cut-off circle
                w_len = math.sqrt(w_sq)
                unit_w = w / w_len
                direction = np.array([unit_w[1], -unit_w[0]])
                u = (r * inv_tau - w_len) * unit_w
            else:  # project on a leg
                leg = math.sqrt(dist_sq - r * r)
                if _det(rel_p, w) > 0:
                    direction = np.array([rel_p[0] * leg - rel_p[1] * r, rel_p[0] * r + rel_p[1] * leg]) / dist_sq
                else:
                    direction = -np.array([rel_p[0] * leg + rel_p[1] * r, -rel_p[0] * r + rel_p[1] * leg]) / dist_sq
                u = float(rel_v @ direction) * direction - rel_v
        else:  # already closer than 2 radius: leave within this step
            inv_dt = 1.0 / dt
            w = rel_v - inv_dt * rel_p
            w_len = float(np.linalg.norm(w))
            unit_w = w / w_len if w_len > _EPS else np.array([1.0, 0.0])
            direction = np.array([unit_w[1], -unit_w[0]])
            u = (r * inv_dt - w_len) * unit_w
        lines.append((v + 0.5 * u, direction))
    fail, new = _lp2(lines, max_speed, np.asarray(v_pref, dtype=float), False)
    if fail < len(lines):
        new = _lp3(lines, fail, max_speed, new)
    return new


@dataclass(frozen=True, eq=False)
class OrcaResult:
    """What :func:`orca` flew: each vehicle's trajectory (sampled every ``dt``) and whether it reached its last
    waypoint."""

    trajectories: dict[str, Trajectory]
    reached: dict[str, bool]


def orca(
    paths: Mapping[str, Sequence[Sequence[float]]],
    min_sep: float,
    speed: float,
    dt: float = 0.05,
    time_horizon: float = 3.0,
    margin: float = 0.05,
    accept: float = 0.05,
    t_max: float = 600.0,
    bias: float = 0.05,
) -> OrcaResult:
    """Fly every vehicle's waypoints ((N, 3) ENU [m]) at up to ``speed`` [m/s] at once, avoiding each other with
        ORCA (see the module doc) as discs of radius ``min_sep / 2 + margin`` [m]; a waypoint is reached within
        ``accept`` [m]. Runs until all are through or ``t_max`` [s]. Each preferred velocity is turned ``bias`` [rad]
    clockwise (a common "pass on the right" rule): exactly symmetric encounters, such as a head-on swap, otherwise
    stall in ORCA (RVO2's own examples perturb the preferred velocities for the same reason)."""
    for name, v in (("min_sep", min_sep), ("speed", speed), ("dt", dt), ("time_horizon", time_horizon)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    names = list(paths)
    wps = {n: np.asarray(paths[n], dtype=float).reshape(-1, 3) for n in names}
    pos = {n: wps[n][0].copy() for n in names}
    vel = {n: np.zeros(2) for n in names}
    nxt = {n: 1 if len(wps[n]) > 1 else 0 for n in names}
    samples = {n: [pos[n].copy()] for n in names}
    radius = 0.5 * min_sep + margin
    cb, sb = math.cos(bias), math.sin(bias)
    turn = np.array([[cb, sb], [-sb, cb]])  # clockwise by bias
    steps = int(math.ceil(t_max / dt))
    k = 0
    for k in range(1, steps + 1):  # noqa: B007 (k is the number of steps flown)
        prefs = {}
        for n in names:
            while nxt[n] < len(wps[n]) - 1 and np.linalg.norm(wps[n][nxt[n]] - pos[n]) <= accept:
                nxt[n] += 1
            to = wps[n][nxt[n]][:2] - pos[n][:2]
            dist = float(np.linalg.norm(to))
            prefs[n] = np.zeros(2) if dist < _EPS else turn @ (to / dist * min(speed, dist / dt))
        new = {}
        for n in names:
            others = [m for m in names if m != n]
            new[n] = orca_velocity(
                pos[n][:2], vel[n], prefs[n], [pos[m][:2] for m in others], [vel[m] for m in others],
                radius, speed, time_horizon, dt,
            )  # fmt: skip
        for n in names:
            vel[n] = new[n]
            dz = wps[n][nxt[n]][2] - pos[n][2]
            pos[n] = np.array(
                [
                    pos[n][0] + vel[n][0] * dt,
                    pos[n][1] + vel[n][1] * dt,
                    pos[n][2] + np.clip(dz, -speed * dt, speed * dt),
                ]
            )
            samples[n].append(pos[n].copy())
        if all(nxt[n] == len(wps[n]) - 1 and np.linalg.norm(wps[n][-1] - pos[n]) <= accept for n in names):
            break
    t = np.arange(k + 1) * dt
    return OrcaResult(
        trajectories={n: Trajectory(t, np.asarray(samples[n])) for n in names},
        reached={n: bool(np.linalg.norm(wps[n][-1] - pos[n]) <= accept) for n in names},
    )

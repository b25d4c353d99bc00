"""Formation flight, as planned references for each vehicle.

- **Virtual structure** (Lewis and Tan 1997): the formation is one rigid body; a virtual point flies the path at
  ``speed`` and turns towards each leg's heading at up to ``yaw_rate`` [rad/s], and each vehicle's reference is its
  slot ``p_c + R(yaw) offset``. No vehicle leads: the slots keep their distances at every instant.
- **Leader–follower** (Desai, Ostrowski and Kumar 1998, the l-psi form with fixed l and psi): the leader flies its
  own trajectory; each follower's reference is the leader's position ``delay`` seconds earlier plus its offset turned
  by the leader's heading then (its course over ground; held while the leader stands still). With a zero offset and a
  delay, a follower flies the leader's track behind it.

Offsets are in the formation's body frame FLU (x forward, y left, z up) [m]; :func:`formation_offsets` makes the
usual shapes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .deconfliction import Trajectory

__all__ = ["SHAPES", "formation_offsets", "leader_follower", "virtual_structure"]

SHAPES = ("line", "column", "wedge")
"""line: abreast, left to right; column: one behind the other; wedge: a V opening backwards, the first at its tip."""


def formation_offsets(shape: str, n: int, spacing: float) -> np.ndarray:
    """(n, 3) FLU offsets [m] of ``shape`` (:data:`SHAPES`) with neighbours ``spacing`` [m] apart, centred on the
    formation's reference point for ``line``; the first vehicle at the reference point otherwise."""
    if shape not in SHAPES:
        raise ValueError(f"formation shape must be one of {', '.join(SHAPES)}, got {shape!r}")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"formation size must be an integer >= 1, got {n!r}")
    if not (math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"formation spacing must be a finite number > 0 [m], got {spacing!r}")
    out = np.zeros((n, 3))
    for i in range(n):
        if shape == "line":
            out[i, 1] = spacing * ((n - 1) / 2 - i)
        elif shape == "column":
            out[i, 0] = -spacing * i
        elif i:
            k = (i + 1) // 2
            side = 1.0 if i % 2 else -1.0
            out[i, :2] = spacing * k * np.array([-math.cos(math.pi / 6), side * math.sin(math.pi / 6)])
    return out


def _rot(yaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def virtual_structure(
    path: Sequence[Sequence[float]],
    offsets: np.ndarray,
    speed: float,
    yaw_rate: float = 0.5,
    dt: float = 0.05,
) -> list[Trajectory]:
    """One trajectory per slot of ``offsets`` (see the module doc) while the virtual point flies ``path`` ((N, 3)
    ENU [m]) at ``speed`` [m/s], waiting at a corner until the structure has turned to the next leg."""
    p = np.asarray(path, dtype=float).reshape(-1, 3)
    off = np.asarray(offsets, dtype=float).reshape(-1, 3)
    for name, v in (("speed", speed), ("yaw_rate", yaw_rate), ("dt", dt)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if len(p) < 2:
        raise ValueError("a formation path needs at least two waypoints")
    legs = np.diff(p, axis=0)
    headings = [math.atan2(d[1], d[0]) for d in legs]
    ts, cs, ys = [], [], []
    t, yaw = 0.0, headings[0]
    for k, d in enumerate(legs):
        target = headings[k]
        while abs(math.remainder(target - yaw, 2 * math.pi)) > 1e-12:  # turn on the spot
            e = math.remainder(target - yaw, 2 * math.pi)
            yaw += max(-yaw_rate * dt, min(yaw_rate * dt, e))
            ts.append(t)
            cs.append(p[k])
            ys.append(yaw)
            t += dt
        n = max(1, math.ceil(float(np.linalg.norm(d)) / (speed * dt)))
        for j in range(n):
            ts.append(t)
            cs.append(p[k] + d * (j / n))
            ys.append(yaw)
            t += float(np.linalg.norm(d)) / speed / n
    ts.append(t)
    cs.append(p[-1])
    ys.append(yaw)
    centre, R = np.asarray(cs), _rot(np.asarray(ys))
    return [Trajectory(np.asarray(ts), centre + R @ o) for o in off]


def leader_follower(
    leader: Trajectory, offsets: np.ndarray, delay: float | Sequence[float] = 0.0, dt: float = 0.05
) -> list[Trajectory]:
    """One trajectory per follower offset (see the module doc), sampled every ``dt`` [s] over the leader's time
    span plus the follower's ``delay`` [s] (one for all or one per follower)."""
    off = np.asarray(offsets, dtype=float).reshape(-1, 3)
    delays = np.broadcast_to(np.asarray(delay, dtype=float), (len(off),))
    if not (np.all(np.isfinite(delays)) and np.all(delays >= 0)):
        raise ValueError(f"delay must be finite and >= 0 [s], got {delay!r}")
    t0, t1 = float(leader.t[0]), leader.t_end
    # the leader's course over ground on each of its intervals, held through stops (the first move's before it)
    v = np.diff(leader.p[:, :2], axis=0)
    if len(v) == 0:
        v = np.zeros((1, 2))
    moving = np.hypot(v[:, 0], v[:, 1]) > 1e-9
    course = np.zeros(len(v))
    last = math.atan2(*v[np.argmax(moving)][::-1]) if moving.any() else 0.0
    for k in range(len(v)):
        if moving[k]:
            last = math.atan2(v[k, 1], v[k, 0])
        course[k] = last
    out = []
    for o, d in zip(off, delays, strict=True):
        t = np.arange(t0, t1 + d + 0.5 * dt, dt)
        tl = np.clip(t - d, t0, t1)
        yaw = course[np.clip(np.searchsorted(leader.t, tl, side="right") - 1, 0, len(course) - 1)]
        out.append(Trajectory(t, leader.at(tl) + _rot(yaw) @ o))
    return out

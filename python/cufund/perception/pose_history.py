"""The recent estimates of a vehicle's pose, looked up at an image's capture time: a detector places its boxes, and
a mission its camera, with the pose at the stamp of the image they came from, which lies between two estimates."""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Iterable, Sequence
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike

from cufund.geometry import quat_to_matrix

__all__ = ["PoseHistory", "pose_at", "slerp"]

_NLERP_BELOW = 1e-6
"""Below this angle between two quaternions [rad] slerp's sin(theta) is ill-conditioned: interpolate linearly and
normalise (the same rotation to well below 1e-12)."""


class _Pose(Protocol):
    @property
    def t(self) -> float: ...
    @property
    def p_W(self) -> np.ndarray: ...
    @property
    def q_WB(self) -> np.ndarray: ...


class _Stamped(NamedTuple):
    t: float
    p_W: np.ndarray
    q_WB: np.ndarray


def slerp(q0: ArrayLike, q1: ArrayLike, s: float) -> np.ndarray:
    """The unit quaternion [w, x, y, z] a fraction ``s`` in [0, 1] of the way from ``q0`` to ``q1`` along the
    shorter great arc (constant angular rate)."""
    a = np.asarray(q0, dtype=float)
    b = np.asarray(q1, dtype=float)
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    dot = float(np.dot(a, b))
    if dot < 0.0:  # q and -q are one rotation: go the short way round
        b, dot = -b, -dot
    theta = math.acos(min(dot, 1.0))
    if theta < _NLERP_BELOW:
        q = (1.0 - s) * a + s * b
    else:
        q = (math.sin((1.0 - s) * theta) * a + math.sin(s * theta) * b) / math.sin(theta)
    return np.asarray(q / np.linalg.norm(q))


def pose_at(poses: Sequence[_Pose], t: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(p_W (3,) [m], R_WB (3, 3)) at time ``t`` [s] from ``poses`` (each with ``t``, ``p_W``, ``q_WB``
    [w, x, y, z]; stamps ascending, e.g. a deque of :class:`~cufund.core.messages.Odometry`): position linear,
    rotation by :func:`slerp` between the two either side of ``t``; None when ``t`` lies outside their span (or
    is not finite)."""
    t = float(t)
    if not poses or not poses[0].t <= t <= poses[-1].t:
        return None
    i = bisect.bisect_right(poses, t, key=lambda s: s.t)  # the first stamp after t; 1 <= i <= len
    if i == len(poses):  # t is the newest stamp
        return np.array(poses[-1].p_W, dtype=float), quat_to_matrix(np.asarray(poses[-1].q_WB, dtype=float), True)
    a, b = poses[i - 1], poses[i]
    s = (t - a.t) / (b.t - a.t) if b.t > a.t else 0.0
    p = (1.0 - s) * np.asarray(a.p_W, dtype=float) + s * np.asarray(b.p_W, dtype=float)
    return p, quat_to_matrix(slerp(a.q_WB, b.q_WB, s))


class PoseHistory:
    """The last ``maxlen`` poses (t [s], p_W [m], q_WB [w, x, y, z]) in time order, checked as they come, and the
    pose at any time they span (:func:`pose_at`)."""

    def __init__(self, maxlen: int = 400) -> None:
        if isinstance(maxlen, bool) or not isinstance(maxlen, (int, np.integer)) or maxlen < 1:
            raise ValueError(f"maxlen must be an integer >= 1 (poses kept), got {maxlen!r}")
        self.maxlen = int(maxlen)
        self._poses: deque[_Stamped] = deque(maxlen=self.maxlen)

    def __len__(self) -> int:
        return len(self._poses)

    def clear(self) -> None:
        self._poses.clear()

    @property
    def t_first(self) -> float | None:
        """The oldest stamp kept [s] (None: empty)."""
        return self._poses[0].t if self._poses else None

    @property
    def t_last(self) -> float | None:
        """The newest stamp kept [s] (None: empty)."""
        return self._poses[-1].t if self._poses else None

    def append(self, t: float, p_W: ArrayLike, q_WB: ArrayLike) -> None:
        """Keeps one pose (the oldest goes once ``maxlen`` are kept). Stamps must not go back in time; a
        non-finite or misshapen input, or a quaternion far from unit length, is a ``ValueError`` naming it."""
        t = float(t)
        p = np.asarray(p_W, dtype=float).reshape(-1)
        q = np.asarray(q_WB, dtype=float).reshape(-1)
        if not math.isfinite(t):
            raise ValueError(f"t must be a finite time [s], got {t!r}")
        if self._poses and t < self._poses[-1].t:
            raise ValueError(f"t must not go back in time: {t} s after {self._poses[-1].t} s")
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"p_W must be 3 finite numbers [m], got {p.tolist()}")
        if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(float(np.linalg.norm(q)) - 1.0) > 1e-3:
            raise ValueError(f"q_WB must be a unit quaternion [w, x, y, z], got {q.tolist()}")
        self._poses.append(_Stamped(t, p, q / np.linalg.norm(q)))

    def extend(self, poses: Iterable[_Pose]) -> None:
        """Appends messages that carry ``t``, ``p_W`` and ``q_WB`` (e.g. :class:`~cufund.core.messages.Odometry`),
        skipping any not newer than the newest kept (a stale or repeated estimate from the bus is not an error;
        :meth:`append` refuses one)."""
        for m in poses:
            if self._poses and float(m.t) <= self._poses[-1].t:
                continue
            self.append(m.t, m.p_W, m.q_WB)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(p_W (3,) [m], R_WB (3, 3)) at time ``t`` [s] (:func:`pose_at`); None outside the span kept."""
        return pose_at(self._poses, t)

    def position_at(self, t: float) -> np.ndarray | None:
        """p_W (3,) [m] at time ``t`` [s] (see :meth:`at`)."""
        pose = self.at(t)
        return None if pose is None else pose[0]

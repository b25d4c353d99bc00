"""What the commander flies: legs (a target with what to do there) and the brake that stops a moving reference."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Brake", "Descend", "Leg"]


class Brake:
    """Stops from p0 at velocity v0, critically damped with time constant tau:
    p = p0 + v0 (2 tau - (2 tau + s) e^(-s/tau)), which comes to rest 2 tau v0 further on."""

    def __init__(self, p0: np.ndarray, v0: np.ndarray, tau: float, yaw: float, t_start: float) -> None:
        self.p0, self.v0, self.tau, self.yaw, self.t_start = np.array(p0, float), np.array(v0, float), tau, yaw, t_start
        self.goal_W = self.p0 + 2 * tau * self.v0

    @property
    def t_end(self) -> float:
        return self.t_start + 10 * self.tau

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        tau, s = self.tau, max(t - self.t_start, 0.0)
        e, v0 = math.exp(-s / tau), self.v0
        return (
            self.p0 + v0 * (2 * tau - (2 * tau + s) * e),
            v0 * ((1 + s / tau) * e),
            v0 * (-(s / tau**2) * e),
            v0 * (-(1 - s / tau) * e / tau**2),
        )


class Descend:
    """Straight down from p0 at ``speed`` [m/s] from ``t_start`` on (the last part of a landing, until touchdown)."""

    def __init__(self, p0: np.ndarray, speed: float, yaw: float, t_start: float) -> None:
        self.p0, self.v = np.array(p0, float), np.array([0.0, 0.0, -float(speed)])
        self.yaw, self.t_start, self.t_end = yaw, t_start, math.inf

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        z = np.zeros(3)
        return self.p0 + self.v * max(t - self.t_start, 0.0), self.v.copy(), z, z


@dataclass
class Leg:
    target: np.ndarray
    yaw: float
    tag: str
    """'takeoff', 'goto', 'item', 'rtl_climb', 'rtl_home' or 'land'."""
    hold_s: float = 0.0
    seq: int = -1
    slow: bool = False
    """Take-off/landing speed limits."""

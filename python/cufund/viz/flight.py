"""What the figures and the replay of a run show, gathered once: the true, estimated and commanded paths, the
planned path, and what the run's parts add (waypoints, gates, a centreline, mission phases, markers, clouds)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.messages import Topics

__all__ = ["Flight", "Gate", "Overlay", "Phase"]


@dataclass(frozen=True)
class Gate:
    """A frame the flight passes through: its opening's centre, axis (the direction flown through) and size."""

    centre_W: np.ndarray
    normal_W: np.ndarray
    width: float
    height: float
    detected: bool = False
    """True: as a detector found it; False: the world's truth."""


@dataclass(frozen=True)
class Phase:
    """A span of the run [s] with its name (a mission state, a part of the reference)."""

    t0: float
    t1: float
    name: str


@dataclass(frozen=True)
class Overlay:
    """Points a part adds to the replay: ``markers`` (a sphere each) or a ``cloud``."""

    name: str
    points_W: np.ndarray
    color: int
    """0xRRGGBB."""
    kind: str = "markers"
    label: str = ""
    """The legend's text (default: ``name``)."""


def _topic(result: Any, topic: Any, *fields: str) -> tuple[np.ndarray, ...]:
    rec = result.topics.get(str(topic), {}) or {}
    t = np.asarray(rec.get("t", np.zeros(0)), dtype=float).reshape(-1)
    out: list[np.ndarray] = [t]
    for name, width in (f.split(":") for f in fields):
        out.append(np.asarray(rec.get(name, np.zeros((0, int(width)))), dtype=float).reshape(-1, int(width)))
    return tuple(out)


@dataclass
class Flight:
    """One run's paths and what its parts add to its figures and replay (the parts append to the lists)."""

    t: np.ndarray
    """Ground-truth times (N,) [s]."""
    p_W: np.ndarray
    """True positions (N, 3) [m]."""
    q_WB: np.ndarray
    """True attitudes (N, 4) [w, x, y, z]."""
    t_est: np.ndarray = field(default_factory=lambda: np.zeros(0))
    p_est_W: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    q_est_WB: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    t_sp: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Trajectory setpoint times (what the controller was asked to fly)."""
    p_sp_W: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    planned_W: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """The planned path sampled over the run (N, 3), or the setpoints when nothing was planned ahead."""
    planned_is_reference: bool = False
    """True: ``planned_W`` is a reference known before the flight; False: the setpoints as published."""
    waypoints_W: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    waypoints_label: str = "waypoints"
    """What the waypoints are ("waypoints", "goal")."""
    gates: list[Gate] = field(default_factory=list)
    centreline_W: np.ndarray | None = None
    """A course's centre line (M, 3): the trajectory figure adds the lateral deviation from it."""
    phases: list[Phase] = field(default_factory=list)
    phases_title: str = "mission phases"
    """What the phases are, above their bands."""
    overlays: list[Overlay] = field(default_factory=list)
    title: str = ""

    @classmethod
    def from_result(cls, result: Any, reference: Any = None, waypoints: Any = None) -> Flight:
        """The paths of a :class:`cufund.simulator.SimulationResult`; ``reference`` (a trajectory) is sampled
        as the planned path, else the setpoints stand for it."""
        s = result.states
        t = np.asarray(s["t"], dtype=float)
        t_est, p_est, q_est = _topic(result, Topics.ESTIMATE, "p_W:3", "q_WB:4")
        t_sp, p_sp = _topic(result, Topics.TRAJECTORY_SETPOINT, "p_W:3")
        if reference is not None and len(t):
            tt = np.linspace(max(t[0], reference.t_start), min(t[-1], reference.t_end), 2000)
            planned, from_reference = np.asarray(reference.sample(tt).p_W, dtype=float), True
        else:
            planned, from_reference = p_sp[:: max(1, len(p_sp) // 3000)], False
        wp = np.zeros((0, 3)) if waypoints is None else np.asarray(waypoints, dtype=float).reshape(-1, 3)
        return cls(
            t,
            np.asarray(s["p_W"], dtype=float),
            np.asarray(s["q_WB"], dtype=float),
            t_est,
            p_est,
            q_est,
            t_sp,
            p_sp,
            planned,
            from_reference,
            wp,
        )

    def airborne_phases(self, lift_m: float = 0.05) -> list[Phase]:
        """Phases read off the truth alone, for a run whose parts name none: on the ground, airborne (from the
        first to the last time the vehicle is ``lift_m`` above where it started), landed."""
        t, z = self.t, self.p_W[:, 2]
        if len(t) < 2:
            return []
        up = np.flatnonzero(z > z[0] + lift_m)
        if not len(up):
            return [Phase(float(t[0]), float(t[-1]), "on the ground")]
        a, b = float(t[up[0]]), float(t[up[-1]])
        spans = [(float(t[0]), a, "on the ground"), (a, b, "airborne"), (b, float(t[-1]), "landed")]
        return [Phase(x, y, name) for x, y, name in spans if y > x]

    def framing_points(self) -> np.ndarray:
        """What a view of the flight must show: the true and planned paths, the waypoints and gates (the estimate
        is left out: a diverged estimate would shrink the flight to a dot)."""
        parts = [self.p_W, self.planned_W, self.waypoints_W] + [g.centre_W.reshape(1, 3) for g in self.gates]
        return np.vstack([np.asarray(p, dtype=float).reshape(-1, 3) for p in parts])

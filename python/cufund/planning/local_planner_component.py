"""The B-spline local replanner as a simulator component: replans on the growing ESDF map towards a goal and
publishes trajectory updates that :class:`~cufund.planning.TrajectoryFollower` stitches."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cufund.core.components import BusView, Planner
from cufund.core.messages import MapUpdate, Odometry, Topics, TrajectoryUpdate

from .bspline import UniformBspline, start_control_points
from .diagnostics import PLANNER_DIAGNOSTICS, PlannerDiagnostics
from .landing import landing
from .local_planner import BsplineLocalPlanner, LocalPlannerParams
from .sequence import Hold, TrajectorySequence
from .trajectory import Trajectory
from .trajectory_follower import stitched

__all__ = ["LocalPlannerComponent", "ReplanRecord"]


@dataclass(frozen=True)
class ReplanRecord:
    """One replan, kept for the run's metrics."""

    t: float
    """Simulated time of the replan [s]."""
    status: str
    """The planner's status ("ok", "collision", "at_goal")."""
    plan_ms: float
    """Wall time of the replan [ms]."""
    min_clearance_m: float
    """Smallest clearance of the candidate trajectory on the map [m]."""
    path_length_m: float
    """Length of the accepted trajectory [m] (0 when rejected)."""
    plan_cpu_ms: float = float("nan")
    """CPU time of the replan [ms] (its wall time less preemption by other processes)."""


class LocalPlannerComponent(Planner):
    """Replans at ``rate_hz`` from the followed reference's own position, velocity and acceleration at the
    replan time (not the measured state), so every update joins the reference with no jump in p, v or a.

    It follows ``initial`` (e.g. the take-off) until ``t_begin``; from then on it replans on the map of the
    latest :class:`~cufund.core.messages.MapUpdate` towards ``goal_W``. A rejected replan keeps the previous
    trajectory. When the map shows the goal closer than the radius (plus ``goal_margin``) to an obstacle, the
    planner aims at the nearest point back along the line to the vehicle that is clear, at most
    ``max_goal_shift`` away (:attr:`active_goal`), as EGO-Planner does. Once the reference is within
    ``goal_tolerance`` of the goal and slow, it brakes to rest there (a short B-spline from the reference's
    state), hovers ``hover_s`` and lands with ``landing`` (a jerk-limited move straight down), after which
    :attr:`t_landed` is set. ``guide_W`` (K, 3) [m], a polyline ending at the goal, is followed while its next
    horizon stays free on the map (a grid A* on the map replaces it where it does not).
    """

    name = "local_planner"

    def __init__(
        self,
        params: LocalPlannerParams,
        goal_W: npt.ArrayLike,
        initial: Trajectory,
        t_begin: float,
        rate_hz: float = 10.0,
        goal_tolerance: float = 0.1,
        hover_s: float = 1.0,
        landing: tuple[float, float, float] = (0.5, 1.0, 3.0),
        yaw: float = 0.0,
        max_goal_shift: float = 1.0,
        goal_margin: float = 0.1,
        guide_W: npt.ArrayLike | None = None,
    ) -> None:
        if not isinstance(params, LocalPlannerParams):
            raise TypeError(f"params must be a LocalPlannerParams, got {type(params).__name__}")
        goal = np.asarray(goal_W, dtype=float)
        if goal.shape != (3,) or not np.all(np.isfinite(goal)):
            raise ValueError(f"goal_W must be 3 finite numbers [m], got {goal_W!r}")
        if not isinstance(initial, Trajectory):
            raise TypeError(f"initial must be a cufund.planning.Trajectory, got {type(initial).__name__}")
        for name, v in (("rate_hz", rate_hz), ("goal_tolerance", goal_tolerance)):
            if not (math.isfinite(v) and float(v) > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        self.params, self.goal_W, self.initial = params, goal, initial
        self.t_begin, self.rate_hz, self.goal_tolerance = float(t_begin), float(rate_hz), float(goal_tolerance)
        self.hover_s, self.landing, self.yaw = float(hover_s), tuple(float(x) for x in landing), float(yaw)
        self.max_goal_shift, self.goal_margin = float(max_goal_shift), float(goal_margin)
        self.guide_W = None if guide_W is None else np.asarray(guide_W, dtype=float).copy()
        """A polyline to ``goal_W`` (e.g. a global plan) the replans follow while it stays free on the map."""
        self.reads = (Topics.ESDF_MAP,)
        self.writes = (Topics.TRAJECTORY_UPDATE, PLANNER_DIAGNOSTICS)
        self.reset()

    def reset(self) -> None:
        self.replans: list[ReplanRecord] = []
        self.reference: Trajectory = self.initial
        """What the follower flies: the initial reference with every published update stitched in."""
        self.t_landed: float | None = None
        """When the landing ends [s], once it is planned."""
        self._planner: BsplineLocalPlanner | None = None
        self._arrived = False
        self.active_goal: np.ndarray = self.goal_W.copy()
        """The goal flown to: ``goal_W``, or the clear point nearest it when the map shows it blocked."""

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if t < self.t_begin or self.t_landed is not None:
            return
        msg: MapUpdate | None = bus.latest(Topics.ESDF_MAP)
        if msg is None:
            return
        if self._planner is None or self._planner.esdf_map is not msg.map:
            self._planner = BsplineLocalPlanner(msg.map, self.params)
            if self.guide_W is not None:
                self._planner.set_guide(self.goal_W, self.guide_W)
        t_r = t + self.latency_s  # the update is followed from when it becomes visible
        ref = self.reference.sample(float(t_r))
        p, v, a = ref.p_W[0], ref.v_W[0], ref.a_W[0]
        if self._arrived:
            if np.linalg.norm(v) < 1e-9 and np.linalg.norm(a) < 1e-9:  # at rest: the hold joins with no jump
                self._land(t, t_r, p, bus)
            return
        goal = self._clear_goal(p)
        if np.linalg.norm(p - goal) <= self.goal_tolerance and np.linalg.norm(v) < 0.1 and np.linalg.norm(a) < 0.3:
            # Arrived (within the tolerance, slow): stop replanning and brake to rest where the reference is.
            q = start_control_points(p, v, a, self.params.dt)
            brake = UniformBspline(np.vstack([q, np.repeat(q[2:], 3, axis=0)]), self.params.dt, t_r, self.yaw)
            self._publish(t, brake, bus)
            self._arrived = True
            return
        plan = self._planner.replan(t_r, p, v, a, goal, self.yaw)
        record = ReplanRecord(
            t, plan.status, 1e3 * plan.plan_seconds, plan.min_clearance, plan.path_length, 1e3 * plan.plan_cpu_seconds
        )
        self.replans.append(record)
        bus.publish(
            PLANNER_DIAGNOSTICS,
            PlannerDiagnostics(
                t,
                "local",
                record.status,
                record.plan_ms,
                record.plan_cpu_ms,
                record.min_clearance_m,
                record.path_length_m,
            ),
        )
        if plan.status == "ok" and plan.trajectory is not None:
            self._publish(t, plan.trajectory, bus)

    def _clear_goal(self, p: np.ndarray) -> np.ndarray:
        """The requested goal when the map shows it clear, else the first clear point on the way back to ``p``
        (5 cm steps, at most ``max_goal_shift``); the last active goal when none is."""
        assert self._planner is not None
        need = self.params.radius + self.goal_margin
        query = self._planner.query
        if query.clearance(self.goal_W) >= need:
            self.active_goal = self.goal_W.copy()
        elif query.clearance(self.active_goal) < need:
            back = p - self.goal_W
            dist = float(np.linalg.norm(back))
            if dist > 1e-9:
                s = np.arange(1, int(min(self.max_goal_shift, dist) / 0.05) + 1) * 0.05
                cand = self.goal_W + s[:, None] * (back / dist)
                ok = np.flatnonzero(query.clearance(cand) >= need)
                if ok.size:
                    self.active_goal = cand[ok[0]]
        return self.active_goal

    def _land(self, t: float, t_r: float, p: np.ndarray, bus: BusView) -> None:
        hold = Hold(p, self.hover_s, self.yaw, t_start=t_r)
        v, a, j = self.landing
        down, self.t_landed = landing(p, 0.0, v, a, j, self.yaw, hold.t_end)  # on to the ground, wherever it is
        self._publish(t, TrajectorySequence([hold, *down.parts]), bus)

    def _publish(self, t: float, trajectory: Trajectory, bus: BusView) -> None:
        self.reference = stitched(self.reference, trajectory, t)
        bus.publish(Topics.TRAJECTORY_UPDATE, TrajectoryUpdate(t, trajectory))

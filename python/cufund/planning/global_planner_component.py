"""The global planner on the map built online: path search (+ min-snap) on the ``esdf`` mapper's live map
(``/map/esdf``, in the estimate's frame), replanned when the newest map shows the plan blocked.

Unknown space is optimistic: a voxel no LiDAR beam has reached counts as free (the map's own convention,
:class:`~cufund.mapping.EsdfMapParams`), so the first plan after take-off runs straight through what has not been
seen yet and bends as the trees come into view. The search keeps to the flight band (``z_min`` .. ``z_max``):
unobserved ground is free to the map too. Only voxels inside the mapped box are plannable (outside it the
clearance is -inf), so the goal must lie in the mapper's box.

Like :class:`~cufund.planning.local_planner_component.LocalPlannerComponent`, the component runs in the simulated
loop at its own rate and publishes :class:`~cufund.core.messages.TrajectoryUpdate` s that the follower stitches;
planning wall time never holds up the controllers (an update is followed from ``t + latency_s``). Never reads
the world: the build gives it no world, and it sees only its state topic and the map.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from cufund.core.components import BusView
from cufund.core.messages import MapUpdate, Odometry, Topics

from .bspline import UniformBspline, start_control_points
from .clearance import ClearanceQuery
from .diagnostics import PLANNER_DIAGNOSTICS, PlannerDiagnostics
from .global_planner import GlobalPlan, GlobalPlanner
from .local_planner import LocalPlannerParams
from .local_planner_component import LocalPlannerComponent, ReplanRecord
from .minimum_snap import MinimumSnapTrajectory
from .point_to_point import JerkLimitedMove
from .trajectory import Trajectory

__all__ = ["GlobalPlannerComponent"]

_log = logging.getLogger(__name__)

_CHECK_DT = 0.02
"""Spacing [s] of the samples of the flown min-snap checked against the newest map (its chords are traced, and
the curve lies within a_max * dt^2 / 8 < 0.2 mm of them)."""


class GlobalPlannerComponent(LocalPlannerComponent):
    """Plans with ``planner`` (a :class:`GlobalPlanner`) on the latest :class:`~cufund.core.messages.MapUpdate`
    from the followed reference's position once ``t_begin`` is reached (the take-off hover: at rest), then:

    - ``local=False``: flies the min-snap. At every step (``rate_hz``) the rest of it is checked against the newest
      map; when it comes closer than the radius to an obstacle there, the reference brakes to rest (a cubic
      B-spline within ``a_max``) and a new plan starts from where it stopped. At the end of the min-snap (at rest
      at the goal) it hovers ``hover_s`` and lands.
    - ``local=True``: the path is the guide of the B-spline local replanner (this class extends
      :class:`LocalPlannerComponent`, whose replans and landing it keeps). The path is searched again when the
      newest map shows its remaining part blocked (closer than the radius), or every ``replan_interval_s``.

    A search that fails (no path on the map, goal against an obstacle or outside the map, ...) is retried at the
    next step; when no plan has succeeded for ``give_up_s``, the reference brakes, hovers ``hover_s`` and lands
    where it is, and :attr:`abort_reason` says why (logged, and ``global_abort`` in the run's metrics).
    ``start_blocked`` of a replan while the local replanner flies does not count: it is the replanner's to leave
    the obstacle's margin.
    """

    name = "global_planner"

    def __init__(
        self,
        planner: GlobalPlanner,
        params: LocalPlannerParams,
        goal_W: npt.ArrayLike,
        initial: Trajectory,
        t_begin: float,
        rate_hz: float = 10.0,
        goal_tolerance: float = 0.1,
        hover_s: float = 1.0,
        landing: tuple[float, float, float] = (0.5, 1.0, 3.0),
        local: bool = False,
        replan_interval_s: float = 1.0,
        give_up_s: float = 5.0,
        yaw: float = 0.0,
    ) -> None:
        if not isinstance(planner, GlobalPlanner):
            raise TypeError(f"planner must be a GlobalPlanner, got {type(planner).__name__}")
        for name, v in (("replan_interval_s", replan_interval_s), ("give_up_s", give_up_s)):
            if isinstance(v, bool) or not (math.isfinite(v) and float(v) > 0):
                raise ValueError(f"{name} must be a finite number > 0 [s], got {v!r}")
        self.planner, self.local = planner, bool(local)
        self.replan_interval_s, self.give_up_s = float(replan_interval_s), float(give_up_s)
        super().__init__(params, goal_W, initial, t_begin, rate_hz, goal_tolerance, hover_s, landing, yaw, guide_W=None)

    def reset(self) -> None:
        super().reset()
        self.global_replans: list[ReplanRecord] = []
        """Every global plan (the first one and the replans)."""
        self.first_plan: GlobalPlan | None = None
        """The first global plan (its figures are the run's ``global_*`` metrics)."""
        self.abort_reason: str | None = None
        """Why the planner gave up and landed (None unless it did)."""
        self._query: ClearanceQuery | None = None
        self._path: np.ndarray | None = None  # the current global path (the guide, or the min-snap's polyline)
        self._flying: MinimumSnapTrajectory | None = None  # local=False: the min-snap being flown
        self._t_plan = -math.inf  # simulated time of the last successful plan
        self._fail_since: float | None = None

    # -- the loop --------------------------------------------------------------------------------------------

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if t < self.t_begin or self.t_landed is not None:
            return
        msg: MapUpdate | None = bus.latest(Topics.ESDF_MAP)
        if msg is None:
            return
        if self._query is None or self._query.esdf_map is not msg.map:
            self._query = ClearanceQuery(msg.map)
        t_r = t + self.latency_s
        ref = self.reference.sample(float(t_r))
        p, v, a = ref.p_W[0], ref.v_W[0], ref.a_W[0]
        at_rest = bool(np.linalg.norm(v) < 1e-9 and np.linalg.norm(a) < 1e-9)
        if self._arrived:
            if at_rest:
                self._land(t, t_r, p, bus)
            return
        if self.local:
            self._guide(t, t_r, p, v, a, bus)
            if not self._arrived:
                super().update(t, state, bus)
        else:
            self._fly(t, t_r, p, v, a, at_rest, bus)

    def _guide(self, t: float, t_r: float, p: np.ndarray, v: np.ndarray, a: np.ndarray, bus: BusView) -> None:
        """local=True: (re)plan the local replanner's guide when due."""
        assert self._query is not None
        due = self._path is None or t - self._t_plan >= self.replan_interval_s - 1e-9 or self._blocked(p)
        if not due:
            return
        first = self.first_plan is None
        plan = self._plan(t, t_r, p, motion=first, bus=bus)
        if plan.ok or (plan.path.found and first):  # a path without a converged min-snap still guides
            self._path = plan.path.path_W
            self._t_plan = t
            self._fail_since = None
            self.guide_W = self._path.copy()
            if self._planner is not None:
                self._planner.set_guide(self.goal_W, self._path)
            return
        if plan.status == "start_blocked" and not first:
            return  # the vehicle is within the margin of an obstacle: the local replanner moves it out
        self._failed(t, t_r, p, v, a, plan.status, bus)

    def _fly(
        self, t: float, t_r: float, p: np.ndarray, v: np.ndarray, a: np.ndarray, at_rest: bool, bus: BusView
    ) -> None:
        """local=False: follow the min-snap; brake when the newest map blocks it; plan again from rest."""
        if self._flying is not None:
            if t_r >= self._flying.t_end:  # at rest at the goal
                self._flying = None
                self._arrived = True
            elif self._blocked_trajectory(t_r):
                self._flying = None
                self._record(t, "blocked", 0.0, 0.0, float("nan"), 0.0, bus)
                self._brake(t, t_r, p, v, a, bus)
            return
        if not at_rest:  # braking
            return
        plan = self._plan(t, t_r, p, motion=True, bus=bus)
        if plan.ok:
            assert plan.trajectory is not None
            self._flying = plan.trajectory
            self._path = plan.path.path_W
            self._t_plan = t
            self._fail_since = None
            self._publish(t, plan.trajectory, bus)
            return
        if plan.status == "start_blocked" and self._step_out(t, t_r, p, bus):
            return  # plan again once at rest outside the search's margin
        self._failed(t, t_r, p, v, a, plan.status, bus)

    def _step_out(self, t: float, t_r: float, p: np.ndarray, bus: BusView) -> bool:
        """At rest closer to an obstacle than the search keeps (radius + margin; e.g. stopped by a brake as the
        map sharpened): move (jerk-limited, at the landing's limits) to the clearest point within 0.6 m whose
        straight way there is certified free at the clearance it starts with, if that point clears the search's
        radius. False when there is none."""
        assert self._query is not None
        need = self.planner.params.radius + self.planner.params.margin
        here = float(self._query.clearance(p))
        if not here > 0.0:
            return False
        dirs = np.array([[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if x or y or z], float)
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        cand = (p + np.concatenate([r * dirs for r in (0.15, 0.3, 0.45, 0.6)])).reshape(-1, 3)
        cand = cand[(cand[:, 2] >= self.params.z_min) & (cand[:, 2] <= self.params.z_max)]
        if cand.shape[0] == 0:
            return False
        clear = np.asarray(self._query.clearance(cand), dtype=float)
        for k in np.argsort(-clear):
            if clear[k] < need:
                return False
            if self._query.segment_free(p, cand[k], min(here, self.planner.params.radius) - 1e-3):
                v, a, j = self.landing
                self._publish(t, JerkLimitedMove(p, cand[k], v, a, j, self.yaw, t_start=t_r), bus)
                self._record(t, "step_out", 0.0, 0.0, float(clear[k]), float(np.linalg.norm(cand[k] - p)), bus)
                return True
        return False

    # -- planning --------------------------------------------------------------------------------------------

    def _plan(self, t: float, t_r: float, p: np.ndarray, motion: bool, bus: BusView) -> GlobalPlan:
        """A plan from ``p`` to the goal on the newest map (the search alone when not ``motion``)."""
        assert self._query is not None
        if motion:
            plan = self.planner.plan(self._query, p, self.goal_W, t_start=t_r, yaw=self.yaw)
            if plan.ok and not self._in_band(plan):
                plan = dataclasses.replace(plan, status="altitude")
        else:
            plan = self.planner.search(self._query, p, self.goal_W)
        if self.first_plan is None:
            self.first_plan = plan
        clearance = plan.motion.min_clearance if plan.motion is not None else float("nan")
        self._record(
            t, plan.status, 1e3 * plan.plan_seconds, 1e3 * plan.plan_cpu_seconds, clearance, plan.path.length, bus
        )
        return plan

    def _in_band(self, plan: GlobalPlan) -> bool:
        """The min-snap stays in the flight band (within 5 cm; the start and goal may lie outside it)."""
        traj = plan.trajectory
        assert traj is not None
        z = traj.sample(np.arange(traj.t_start, traj.t_end + 1e-9, _CHECK_DT)).p_W[:, 2]
        z0 = float(plan.path.path_W[0, 2])
        lo, hi = min(self.params.z_min, z0, float(self.goal_W[2])), max(self.params.z_max, z0, float(self.goal_W[2]))
        return bool(z.min() >= lo - 0.05 and z.max() <= hi + 0.05)

    def _blocked(self, p: np.ndarray) -> bool:
        """The current path from the point nearest ``p`` on comes closer than the radius to the newest map's
        obstacles."""
        assert self._query is not None and self._path is not None
        g = self._path
        a, b = g[:-1], g[1:]
        ab = b - a
        u = np.clip(np.einsum("kd,kd->k", p - a, ab) / np.maximum(np.einsum("kd,kd->k", ab, ab), 1e-12), 0, 1)
        k = int(np.argmin(np.linalg.norm(a + u[:, None] * ab - p, axis=1)))
        rest = np.vstack([a[k] + u[k] * ab[k], g[k + 1 :]])
        if rest.shape[0] < 2:
            return False
        return not bool(self._query.path_free(rest, self.planner.params.radius).all())

    def _blocked_trajectory(self, t_r: float) -> bool:
        """The rest of the flown min-snap comes closer than the radius to the newest map's obstacles."""
        assert self._query is not None and self._flying is not None
        ts = np.append(np.arange(t_r, self._flying.t_end, _CHECK_DT), self._flying.t_end)
        curve = self._flying.sample(ts).p_W
        return not bool(self._query.path_free(curve, self.planner.params.radius).all())

    # -- braking, giving up ----------------------------------------------------------------------------------

    def _brake(self, t: float, t_r: float, p: np.ndarray, v: np.ndarray, a: np.ndarray, bus: BusView) -> None:
        """Brake to rest from the reference's (p, v, a): the cubic B-spline Q0, Q1, Q2, Q2, Q2, Q2, whose
        acceleration control points are a and -(v / dt + a / 2); dt is chosen so the second stays within
        ``a_max`` (the stop is about |v| dt ahead)."""
        a_max = self.params.a_max
        speed, acc = float(np.linalg.norm(v)), float(np.linalg.norm(a))
        dt = max(self.params.dt, speed / max(a_max - 0.5 * acc, 0.25 * a_max))
        q = start_control_points(p, v, a, dt)
        self._publish(t, UniformBspline(np.vstack([q, np.repeat(q[2:], 3, axis=0)]), dt, t_r, self.yaw), bus)

    def _failed(
        self, t: float, t_r: float, p: np.ndarray, v: np.ndarray, a: np.ndarray, status: str, bus: BusView
    ) -> None:
        if self._fail_since is None:
            self._fail_since = t
        if t - self._fail_since < self.give_up_s - 1e-9:
            return
        self.abort_reason = (
            f"global planner: no {self.planner.params.search} plan to the goal {self.goal_W.tolist()} on the online "
            f"map for {self.give_up_s:g} s (last status: {status}); hovering, then landing at "
            f"{np.round(p, 2).tolist()}"
        )
        _log.warning(self.abort_reason)
        self._record(t, "gave_up", 0.0, 0.0, float("nan"), 0.0, bus)
        if np.linalg.norm(v) > 1e-9 or np.linalg.norm(a) > 1e-9:
            self._brake(t, t_r, p, v, a, bus)
        self._flying = None
        self._arrived = True  # land once at rest (after hover_s)

    def _record(
        self, t: float, status: str, plan_ms: float, cpu_ms: float, clearance: float, length: float, bus: BusView
    ) -> None:
        record = ReplanRecord(t, status, plan_ms, clearance, length, cpu_ms)
        self.global_replans.append(record)
        if not self.local:
            self.replans.append(record)
        bus.publish(PLANNER_DIAGNOSTICS, PlannerDiagnostics(t, "global", status, plan_ms, cpu_ms, clearance, length))

    # -- metrics ---------------------------------------------------------------------------------------------

    def global_metrics(self) -> dict[str, Any]:
        """The ``global_*`` figures of the first plan (the keys of the known-map planner), and the replans' (wall
        time of every search, first plan included)."""
        ms = np.array([r.plan_ms for r in self.global_replans if r.status not in ("blocked", "gave_up", "step_out")])
        return {
            **plan_metrics(self.first_plan, self.planner.params.search),
            "global_replans": sum(r.status not in ("blocked", "gave_up", "step_out") for r in self.global_replans),
            "global_replan_status": _counts(r.status for r in self.global_replans),
            "global_replan_ms_median": float(np.median(ms)) if ms.size else None,
            "global_replan_ms_max": float(ms.max()) if ms.size else None,
            "global_abort": self.abort_reason,
        }


def plan_metrics(plan: GlobalPlan | None, search: str) -> dict[str, Any]:
    """``global_status``, ``global_plan_ms``, ... of one plan (None where it has no such figure)."""
    if plan is None:
        return {"global_status": "not_planned", "global_search": search}
    m = plan.motion
    f = None if m is None else m.feasibility
    return {
        "global_status": plan.status,
        "global_search": search,
        "global_plan_ms": 1e3 * plan.plan_seconds,
        "global_search_ms": 1e3 * plan.search_seconds,
        "global_motion_ms": 1e3 * plan.motion_seconds,
        "global_plan_cpu_ms": 1e3 * plan.plan_cpu_seconds,
        "global_path_length_m": plan.path.length if plan.path.found else None,
        "global_path_vertices": int(plan.path.path_W.shape[0]),
        "global_inserted_waypoints": None if m is None else m.inserted,
        "global_min_map_clearance_m": None if m is None else m.min_clearance,
        "global_duration_s": None if m is None else m.trajectory.duration,
        "global_peak_speed_mps": None if f is None else f.peak_speed,
        "global_peak_acceleration_mps2": None if f is None else f.peak_acceleration,
        "global_peak_jerk_mps3": None if f is None else f.peak_jerk,
        "global_max_tilt_deg": None if f is None else f.max_tilt_deg,
    }


def _counts(statuses: Any) -> dict[str, int]:
    out: dict[str, int] = {}
    for s in statuses:
        out[s] = out.get(s, 0) + 1
    return out

"""The tunnel mission (paper §3.2): a state machine that initialises on the pad, takes off, detects the course's
frames, flies through them and lands beyond the last one — all on the LiDAR-inertial estimate.

States (published as :class:`~cufund.core.messages.MissionState` on ``/mission/state``):

``initialise``  on the pad, rotors idle, while the LIO initialises statically (``init_s``);
``takeoff``     a jerk-limited climb to ``takeoff_height``;
``detect``      hover until the detector reports the first frame, confident and stable (``detect_timeout_s``:
                none -> ``aborted``, land where it is);
``align``       a straight move onto the first frame's axis, ``align_m`` before it at its opening's height; hover
                there until every expected frame is detected, confident and stable (after ``detect_timeout_s``
                creep along the axis to ``creep_m`` before the frame and wait once more; still fewer frames ->
                ``aborted``, land there, never entering a frame);
``enter``       min-snap along the first frame's re-detected axis to its centre, at rest; hover ``hold_s``
                (paper: "the MAV is guided to the centre of the first tunnel wall");
``through``     re-plan with the newest detections from the first centre through every opening along its normal
                (approach and exit points on each frame's axis) to ``exit_m`` beyond the last one (paper: "the
                furthermost centre is used as the planning goal");
``land``        hover ``hold_s``, then straight down;

An unhealthy estimator (LiDAR frames missing for ``lidar_silence_s``, or its diagnostics saying so) at a rest
point (detect, align, enter) holds the hover; the failsafe supervisor (:mod:`.failsafe_supervisor`, watching the
same :class:`~.failsafe_health.EstimatorHealth`) lands it (outside the course) unless it recovers in
``failsafe.COM_POS_FS_DELAY + COM_FAIL_ACT_T`` (1 + 5 s); while flying through the course the planned path is kept (stopping inside the course gains nothing;
the LIO propagates on the IMU) and the spell is recorded; an estimate older than ``stale_s`` lands at once.
``done`` / ``aborted`` (with the reason).

``through: stepwise`` (a forward camera, which sees the frames one by one) enters once the first frame is confident
and stable and flies frame by frame: ``enter`` and ``through`` are hops through one frame each to a rest point on its
axis past it, facing along it; ``wait`` holds there until the next frame (the nearest one ``next_min_m`` beyond the
last passed frame's plane, within ``max_gap_m``) is confident and stable (``detect_timeout_s``: none -> ``aborted``,
landing there when the descent is clear of the passed bars, else backing out of the course); the last hop goes on
``exit_m`` beyond the last frame and lands.

Every plan is a minimum-snap trajectory kept within ``corridor`` of its waypoint polyline (waypoints inserted
where it strays) and checked against the *detected* frames' bars (:mod:`.tunnel_geometry`): a plan that comes
closer than ``clearance`` to one is never flown. The mission never reads ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.components import BusView, Planner
from cufund.core.config import ConfigError, check_at_most
from cufund.core.messages import MissionState, Odometry, Topics, TrajectoryUpdate, TunnelEstimate
from cufund.planning.landing import landing
from cufund.planning.min_snap_planner import MinSnapPlanner, MinSnapPlannerParams
from cufund.planning.point_to_point import JerkLimitedMove
from cufund.planning.sequence import Hold, TrajectorySequence
from cufund.planning.trajectory import Trajectory
from cufund.planning.trajectory_follower import stitched

from .failsafe_health import EstimatorHealth
from .tunnel_geometry import frame_boxes

__all__ = ["TunnelMission", "TunnelMissionParams"]

_FOREVER = 1e6


@dataclass(frozen=True)
class TunnelMissionParams:
    """The tunnel mission's knobs. Lengths [m], times [s], speeds [m/s], accelerations [m/s^2]."""

    frames: int = 5
    """Frames the course has (the competition's rules): fewer detected -> abort and land."""
    takeoff_height: float = 1.0
    """Hover height above the pad while detecting [m]."""
    init_s: float = 1.5
    """Time on the pad before take-off (the LIO's static initialisation needs >= 1 s) [s]."""
    detect_timeout_s: float = 15.0
    """Longest hover waiting for the detections [s]."""
    min_confidence: float = 0.2
    """Every expected frame needs at least this confidence."""
    stable_updates: int = 3
    """Consecutive detections whose centres moved less than ``stable_m``."""
    stable_m: float = 0.02
    """Largest centre change between stable detections [m]."""
    align_m: float = 1.0
    """Straight approach on the first frame's axis [m]."""
    creep_m: float = 0.5
    """Still missing frames after ``detect_timeout_s`` at the align point: creep along the axis to this far before
    the first frame and wait once more [m]."""
    axis_m: float = 0.25
    """Approach and exit points on each frame's axis (at most 0.4 x the gap to the neighbouring frame) [m]."""
    exit_m: float = 1.0
    """Landing point beyond the last frame along its axis [m]."""
    hold_s: float = 1.0
    """Hover at the first centre and before landing [s]."""
    v_max: float = 0.6
    """Min-snap speed limit [m/s]."""
    a_max: float = 1.0
    """Min-snap acceleration limit [m/s^2]."""
    corridor: float = 0.03
    """Half-width of the tube around the waypoint polyline the min-snap path stays in [m]."""
    clearance: float = 0.17
    """Smallest distance from a planned position to a detected bar [m] (the vehicle's half-diagonal + margin)."""
    bar: float = 0.05
    """Thickness of the frames' bars (the rules), for the plan check [m]."""
    move_v_max: float = 0.5
    """Take-off and landing speed limit [m/s]."""
    move_a_max: float = 1.0
    """Take-off and landing acceleration limit [m/s^2]."""
    move_j_max: float = 3.0
    """Take-off and landing jerk limit [m/s^3]."""
    rate_hz: float = 20.0
    """State machine rate [Hz]."""
    stale_s: float = 0.5
    """An estimate older than this is a lost estimator: hover, then land [s]."""
    lidar_silence_s: float = 0.35
    """The estimator is unhealthy when its newest LiDAR frame diagnostics are older than this [s]."""
    health_wait_s: float = 3.0
    """Superseded by the failsafe supervisor's COM_POS_FS_DELAY + COM_FAIL_ACT_T (the tunnel kind refuses another
    value and names those) [s]."""
    through: str = "all"
    """How the course is flown. ``all``: wait at the align point until every expected frame is detected, confident
    and stable, then one plan through all of them (a LiDAR sees the whole course from there). ``stepwise``: enter
    as soon as the first frame is, then frame by frame: each hop goes through the next frame to a rest point just
    past it, where the mission waits (``detect_timeout_s``) for the one after (a forward camera sees the frames
    one by one; ``perception: camera`` selects it)."""
    next_min_m: float = 0.3
    """Stepwise: a detected frame is taken as the next one only when its centre lies at least this far beyond the
    last passed frame's plane (the nearest such frame) [m]."""
    max_gap_m: float = 2.0
    """Stepwise: the largest distance between consecutive frames' centres the course's rules allow (the generated
    courses: 1.5 m ahead, 0.3 m aside, 0.2 m up or down) and a margin: a detected frame farther than this from the
    last passed one is not taken as the next (an undetected frame lies between) [m]. A frame nearer than this may
    still have an undetected one between (the rules' spacing, 0.5-1.5 m, puts the frame after next 1.0 m on or
    more): the hop to it is checked against the detected bars only, crosses the hidden frame's plane unchecked
    and counts one frame short. Below 1.0 m that cannot happen, but every wider gap then ends the flight."""

    def __post_init__(self) -> None:
        if isinstance(self.frames, bool) or not isinstance(self.frames, int) or self.frames < 1:
            raise ConfigError(f"mission.frames must be an integer >= 1, got {self.frames!r}")
        if isinstance(self.stable_updates, bool) or not isinstance(self.stable_updates, int) or self.stable_updates < 1:
            raise ConfigError(f"mission.stable_updates must be an integer >= 1, got {self.stable_updates!r}")
        for name in (
            "takeoff_height",
            "init_s",
            "detect_timeout_s",
            "stable_m",
            "align_m",
            "creep_m",
            "axis_m",
            "exit_m",
            "v_max",
            "a_max",
            "corridor",
            "clearance",
            "bar",
            "move_v_max",
            "move_a_max",
            "move_j_max",
            "rate_hz",
            "stale_s",
            "lidar_silence_s",
            "health_wait_s",
            "next_min_m",
            "max_gap_m",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and float(v) > 0):
                raise ConfigError(f"mission.{name} must be a finite number > 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        check_at_most(self, "mission", rate_hz=1e3, frames=1000)
        for name in ("min_confidence", "hold_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and float(v) >= 0):
                raise ConfigError(f"mission.{name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.through not in ("all", "stepwise"):
            raise ConfigError(f"mission.through must be 'all' or 'stepwise', got {self.through!r}")
        if self.init_s < 1.0:
            raise ConfigError(f"mission.init_s must be >= 1 s (the LIO's static initialisation), got {self.init_s!r}")


@dataclass
class PlanRecord:
    """One plan the mission made (kept for the metrics and plots)."""

    t: float
    leg: str
    ok: bool
    reason: str
    waypoints: np.ndarray
    trajectory: Any = None
    plan_ms: float = 0.0
    min_clearance_m: float = math.inf
    """Smallest distance of the planned path to the detected bars [m]."""


@dataclass
class _Detections:
    centres: np.ndarray
    normals: np.ndarray
    sizes: np.ndarray

    def __add__(self, other: _Detections) -> _Detections:
        """These frames, then ``other``'s."""
        return _Detections(
            np.concatenate([self.centres, other.centres]),
            np.concatenate([self.normals, other.normals]),
            np.concatenate([self.sizes, other.sizes]),
        )


class TunnelMission(Planner):
    """The state machine (see the module docstring). ``pad_W`` is the pad position, ``yaw`` the heading held
    throughout [rad]. The flown reference is :attr:`reference` (a follower stitches the published updates)."""

    name = "tunnel_mission"

    def __init__(self, params: TunnelMissionParams, pad_W: Any, yaw: float = 0.0, wait_for_start: bool = False) -> None:
        self.wait_for_start = bool(wait_for_start)
        """Flown under a commander: wait in ``initialise`` until :meth:`start` (the operator's Start)."""
        if not isinstance(params, TunnelMissionParams):
            raise TypeError(f"params must be a TunnelMissionParams, got {type(params).__name__}")
        self.params, self.pad_W, self.yaw = params, np.asarray(pad_W, dtype=float), float(yaw)
        self.rate_hz = params.rate_hz
        self.reads = (Topics.TUNNEL_ESTIMATE,)
        self.optional_reads = (Topics.ESTIMATOR_DIAGNOSTICS,)
        self.writes = (Topics.TRAJECTORY_UPDATE, Topics.MISSION_STATE)
        self.initial = Hold(self.pad_W, _FOREVER, self.yaw, t_start=0.0)
        self.planner = MinSnapPlanner(
            MinSnapPlannerParams(
                v_max=params.v_max, a_max=params.a_max, optimize_times=True, corridor=params.corridor, max_waypoints=200
            )
        )
        self.reset()

    def reset(self) -> None:
        import time

        self.cpu_start_s = time.process_time()
        """Process CPU time at the start of the run [s] (for the run's CPU real-time factor)."""
        self.reference: Trajectory = self.initial
        self.state, self.reason, self.progress = "initialise", "", 0
        self.t_go: float | None = None if self.wait_for_start else 0.0
        """When the mission was started (0 without ``wait_for_start``; None while it waits) [s]."""
        if self.wait_for_start:
            self.reason = "waiting for the operator's start"
        self.transitions: list[tuple[float, str, str]] = [(0.0, "initialise", "")]
        self.plans: list[PlanRecord] = []
        self.detections: list[tuple[float, TunnelEstimate]] = []
        self.first: _Detections | None = None
        """The newest stable detection of the first frame."""
        self.complete: _Detections | None = None
        """The newest stable detection of every expected frame."""
        self.used: _Detections | None = None
        """The detections the flown plan goes through."""
        self.t_end: float | None = None
        """When the reference comes to rest on the ground (landing's end) [s]."""
        self._t_state = 0.0
        self._t_leg_end = math.inf
        if getattr(self, "health", None) is None:  # kept across runs: the failsafe supervisor holds the same one
            self.health = EstimatorHealth(self.params.lidar_silence_s)
            """The estimator's health, the failsafe supervisor's too (one monitor: it lands when the mission waits)."""
        self.health.reset()
        self._failsafe: tuple[str, str] | None = None  # a failsafe's land request (action, reason), done at once
        self._stable = 0
        self._crept = False
        self._best = 0
        self._last: np.ndarray | None = None
        self._published = -1
        self.heading = self.yaw
        """The yaw the reference holds at rest [rad] (stepwise: the last passed frame's heading)."""
        self.passed: _Detections | None = None
        """Stepwise: the detections of the frames passed so far, as each hop planned through them."""
        self._target: _Detections | None = None  # stepwise: the frame the current hop goes through
        self._last_hop = False
        self._failsafe_urgent = False

    # -- helpers ---------------------------------------------------------------------------------------------
    def _enter(self, t: float, state: str, reason: str, bus: BusView) -> None:
        self.state, self.reason, self._t_state = state, reason, t
        self.transitions.append((t, state, reason))
        bus.publish(Topics.MISSION_STATE, MissionState(t, state, reason, self.progress))

    def _publish(self, t: float, trajectory: Trajectory, bus: BusView) -> None:
        self.reference = stitched(self.reference, trajectory, t)
        bus.publish(Topics.TRAJECTORY_UPDATE, TrajectoryUpdate(t, trajectory))

    def _abort(self, t: float, t_r: float, reason: str, bus: BusView, back_W: np.ndarray | None = None) -> None:
        """Hover where the reference is (at rest in every state this is called from), then land (first back out
        to ``back_W`` when given: from inside a frame's opening, straight down would meet its bottom bar)."""
        p = self.reference.sample(float(t_r)).p_W[0]
        if back_W is not None:
            self._move(t, t_r, np.asarray(back_W, dtype=float), bus)
            t_r, p = self._t_leg_end, np.asarray(back_W, dtype=float)
        if p[2] - self.pad_W[2] > 0.05:
            self._land(t, t_r, p, bus)
        else:
            self.t_end = t_r
        self._enter(t, "aborted", reason, bus)

    def _land(self, t: float, t_r: float, p: np.ndarray, bus: BusView) -> None:
        pp = self.params
        hold = Hold(p, pp.hold_s, self.heading, t_start=t_r)
        down, self.t_end = landing(
            p, float(self.pad_W[2]), pp.move_v_max, pp.move_a_max, pp.move_j_max, self.heading, hold.t_end
        )
        self._publish(t, TrajectorySequence([hold, *down.parts]), bus)

    @property
    def finished(self) -> bool:
        return self.state in ("done", "aborted")

    # -- the state machine -----------------------------------------------------------------------------------
    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        pp = self.params
        t_r = t + self.latency_s
        est: TunnelEstimate | None = bus.latest(Topics.TUNNEL_ESTIMATE)
        if est is not None and (not self.detections or self.detections[-1][1] is not est):
            self.detections.append((t, est))
            self._track_stability(est)
            self._count(est)
            if self._stable >= pp.stable_updates:
                self._latch(est)
        healthy, _ = self.health.update(t)
        if self.state in ("done", "aborted"):
            return
        at_rest = self.state in ("detect", "wait") or (self.state in ("align", "enter") and t_r >= self._t_leg_end)
        if self._failsafe is not None and pp.through == "stepwise":
            self._failsafe_stepwise(t, t_r, bus)
            return
        if self._failsafe is not None:  # the failsafe supervisor lands the vehicle (outside the course)
            back = self._align_point(self.used) if self.state == "enter" and self.used is not None else None
            self._abort(t, t_r, f"failsafe: {self._failsafe[1]}", bus, back_W=back)
            return
        if not healthy and at_rest:  # hover (the reference holds) while the estimator recovers; else the failsafe lands
            return
        if self.state == "initialise":
            if self.t_go is not None and t >= self.t_go + pp.init_s:
                top = self.pad_W + np.array([0.0, 0.0, pp.takeoff_height])
                self._move(t, t_r, top, bus)
                self._enter(t, "takeoff", "", bus)
            return
        if self.state == "takeoff":
            if t_r >= self._t_leg_end:
                self._enter(t, "detect", "", bus)
            return
        if pp.through == "stepwise" and self.state != "land":
            self._update_stepwise(t, t_r, state, est, bus)
            return
        if self.state == "detect":  # the first frame, confident and stable: fly onto its axis
            d = self.complete or self.first
            if d is not None:
                self._plan_align(t, t_r, d, bus)
            elif t - self._t_state > pp.detect_timeout_s:
                self._abort(
                    t, t_r, f"detected {self._count(est)} of {pp.frames} frames in {pp.detect_timeout_s:g} s", bus
                )
            return
        if self.state == "align":  # on the first frame's axis: wait for every frame, confident and stable
            if t_r < self._t_leg_end:
                return
            if self.complete is not None:
                self._plan_enter(t, t_r, self.complete, bus)
            elif t_r - self._t_leg_end > pp.detect_timeout_s:
                d = self.first or self.used
                if not self._crept and d is not None and pp.creep_m < pp.align_m:
                    # creep closer along the axis (still before the frame) for a better view of the course
                    self._crept = True
                    n0 = d.normals[0] / np.linalg.norm(d.normals[0])
                    self._move(t, t_r, d.centres[0] - pp.creep_m * n0, bus)
                    return
                self._abort(
                    t, t_r, f"detected {self._count(est)} of {pp.frames} frames in {pp.detect_timeout_s:g} s", bus
                )
            return
        if self.state == "enter":  # at the first centre: re-plan through every opening with the newest detections
            if t_r >= self._t_leg_end + pp.hold_s:
                detections = self.complete or self.used
                assert detections is not None  # the enter leg is planned from detections
                self._plan_through(t, t_r, detections, bus)
            return
        if self.state == "through":
            self._count_progress(state)
            if t_r >= self._t_leg_end:
                self.progress = pp.frames
                p = self.reference.sample(float(t_r)).p_W[0]
                self._land(t, t_r, p, bus)
                self._enter(t, "land", "", bus)
            return
        if self.state == "land" and self.t_end is not None and t_r >= self.t_end:
            self._enter(t, "done", "", bus)

    def setup(self, bus: BusView) -> None:
        self.health.setup(bus)

    @property
    def health_events(self) -> list[tuple[float, float, str]]:
        """Spells of an unhealthy estimator: (start [s], length [s], reason)."""
        return self.health.events

    def failsafe(self, t: float, action: str, reason: str, urgent: bool) -> str:
        """A failsafe supervisor's request (:class:`~cufund.missions.failsafe_takeover.MissionTakeover`): 'hold'
        is what the mission does by itself at its rest points; 'land' and 'rtl' land outside the course at the
        next step (backing out of the first opening), except through the course where the path ends in a
        landing beyond the last frame anyway (an urgent one, a motor failure, lands at once). Returns what it did
        when that is not what was asked ('' when it is)."""
        if self.finished:
            return f"the mission has {self.state} already"
        if action == "hold":
            return (
                "the mission holds at its rest points"
                if self.state != "through"
                else "the mission keeps its path through the course"
            )
        stepwise_hop = self.params.through == "stepwise" and self.state in ("enter", "through")
        if stepwise_hop and not self._last_hop and not urgent:  # backs out once at rest past the frame
            self._failsafe, self._failsafe_urgent = (action, reason), False
            return "the mission ends its hop past the frame, then lands there (clear of the bars) or backs out of the course"
        if self.state in ("through", "land") and not urgent:
            return "the mission's path through the course ends in a landing beyond the last frame"
        self._failsafe, self._failsafe_urgent = (action, reason), bool(urgent)
        return "the tunnel mission lands instead of returning through the course" if action == "rtl" else ""

    def _latch(self, est: TunnelEstimate) -> None:
        """Keeps the newest stable detections: of the first frame (:attr:`first`) and of every expected frame
        (:attr:`complete`), so a detector that loses sight of a frame for a while does not undo them."""
        d = self._confident(est, self.params.frames)
        if d is not None:
            self.complete = d
        d1 = self._confident(est, 1)
        if d1 is not None:
            self.first = d1

    def _track_stability(self, est: TunnelEstimate) -> None:
        """Counts consecutive detections whose centres moved less than ``stable_m`` (same number of frames)."""
        c = np.asarray(est.centres_W, dtype=float)
        last = self._last
        same = (
            last is not None
            and last.shape == c.shape
            and c.shape[0] > 0
            and float(np.max(np.linalg.norm(last - c, axis=1))) < self.params.stable_m
        )
        self._stable = self._stable + 1 if same else 0
        self._last = c

    def _count(self, est: TunnelEstimate | None) -> int:
        """The most frames seen confident at once so far."""
        if est is not None:
            self._best = max(
                self._best, int(np.count_nonzero(np.asarray(est.confidence) >= self.params.min_confidence))
            )
        return self._best

    def _move(self, t: float, t_r: float, goal: np.ndarray, bus: BusView) -> None:
        """A jerk-limited straight move at rest from the reference's position to ``goal``, then hold there."""
        pp = self.params
        p = self.reference.sample(float(t_r)).p_W[0]
        mv = JerkLimitedMove(p, goal, pp.move_v_max, pp.move_a_max, pp.move_j_max, self.heading, t_start=t_r)
        self._publish(t, TrajectorySequence([mv, Hold(goal, _FOREVER, self.heading, t_start=mv.t_end)]), bus)
        self._t_leg_end = mv.t_end

    def _confident(self, est: TunnelEstimate | None, k: int) -> _Detections | None:
        """The first ``k`` frames of ``est`` (ordered along the course) when it holds at least ``k`` and each of
        them is confident enough, else None."""
        if est is None:
            return None
        conf = np.asarray(est.confidence, dtype=float)
        if conf.shape[0] < k or np.any(conf[:k] < self.params.min_confidence):
            return None
        return _Detections(
            np.asarray(est.centres_W, float)[:k].copy(),
            np.asarray(est.normals_W, float)[:k].copy(),
            np.asarray(est.opening_sizes, float)[:k].copy(),
        )

    def _count_progress(self, state: Odometry) -> None:
        """Frames passed, on the estimate: the estimated position is ahead of the next frame's plane."""
        d = self.used
        if d is None:
            return
        k = self.progress
        while k < d.centres.shape[0] and (np.asarray(state.p_W) - d.centres[k]) @ d.normals[k] > 0.1:
            k += 1
        self.progress = k

    # -- planning --------------------------------------------------------------------------------------------
    def _axis_points(self, d: _Detections, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The approach and exit points on frame k's axis, at most 0.4 x the gap to its neighbours apart."""
        gaps = []
        if k > 0:
            gaps.append(np.linalg.norm(d.centres[k] - d.centres[k - 1]))
        if k + 1 < d.centres.shape[0]:
            gaps.append(np.linalg.norm(d.centres[k + 1] - d.centres[k]))
        a = min([self.params.axis_m] + [0.4 * g for g in gaps])
        n = d.normals[k] / max(np.linalg.norm(d.normals[k]), 1e-12)
        return d.centres[k] - a * n, d.centres[k] + a * n

    def _plan(
        self, t: float, t_r: float, leg: str, waypoints: np.ndarray, d: _Detections, yaw: np.ndarray | None = None
    ) -> PlanRecord:
        """A min-snap plan through ``waypoints`` (holding :attr:`yaw`, or ``yaw`` per waypoint [rad]) checked against
        the bars of ``d``."""
        import time

        pp = self.params
        w0 = time.perf_counter()
        keep = np.concatenate([[True], np.linalg.norm(np.diff(waypoints, axis=0), axis=1) > 0.05])  # no tiny legs
        waypoints = waypoints[keep]
        psi = np.full(waypoints.shape[0], self.yaw) if yaw is None else np.asarray(yaw, dtype=float)[keep]
        rec = PlanRecord(t, leg, False, "", waypoints)
        try:
            res = self.planner.plan(waypoints, psi, t_start=t_r)
        except (ValueError, np.linalg.LinAlgError) as e:
            rec.reason = f"min-snap failed: {e}"
        else:
            tr = res.trajectory
            ts = np.arange(tr.t_knots[0], tr.t_end, 0.01)
            c = float(frame_boxes(d.centres, d.normals, d.sizes, pp.bar).distance(tr.sample(ts).p_W).min())
            rec.trajectory, rec.min_clearance_m = tr, c
            if res.status != "ok":
                rec.reason = f"min-snap did not stay within {pp.corridor} m of its waypoints"
            elif c < pp.clearance:
                rec.reason = f"plan passes {c:.3f} m from a detected bar (< {pp.clearance} m)"
            else:
                rec.ok = True
        rec.plan_ms = 1e3 * (time.perf_counter() - w0)
        self.plans.append(rec)
        return rec

    def _narrow(self, d: _Detections) -> str:
        need = 2 * self.params.clearance
        bad = [k for k in range(d.sizes.shape[0]) if min(d.sizes[k]) < need]
        return (
            ""
            if not bad
            else (
                f"opening {bad[0] + 1} ({d.sizes[bad[0], 0]:.2f} x {d.sizes[bad[0], 1]:.2f} m) "
                f"is narrower than the vehicle needs ({need:.2f} m)"
            )
        )

    def _align_point(self, d: _Detections) -> np.ndarray:
        n0 = d.normals[0] / np.linalg.norm(d.normals[0])
        return d.centres[0] - self.params.align_m * n0

    def _plan_align(self, t: float, t_r: float, d: _Detections, bus: BusView) -> None:
        """Onto the first frame's axis, ``align_m`` before it at its opening's height (nothing lies between)."""
        narrow = self._narrow(d)
        if narrow:
            self._abort(t, t_r, narrow, bus)
            return
        self.used = d
        self._move(t, t_r, self._align_point(d), bus)
        self._enter(t, "align", "", bus)

    def _plan_enter(self, t: float, t_r: float, d: _Detections, bus: BusView) -> None:
        """From the align point along the first frame's (re-detected) axis to its centre, at rest."""
        narrow = self._narrow(d)
        if narrow:
            self._abort(t, t_r, narrow, bus)
            return
        p = self.reference.sample(float(t_r)).p_W[0]
        before, _ = self._axis_points(d, 0)
        n0 = d.normals[0] / np.linalg.norm(d.normals[0])
        ahead = float((p - d.centres[0]) @ n0)  # < 0: before the frame; past the align point after a creep
        via = [self._align_point(d)] if ahead < -self.params.align_m + 0.05 else [d.centres[0] + ahead * n0]
        rec = self._plan(t, t_r, "enter", np.array([p, *via, before, d.centres[0]]), d)
        if not rec.ok:
            self._abort(t, t_r, f"no safe path into the first frame: {rec.reason}", bus)
            return
        self.used = d
        tr = rec.trajectory
        self._publish(t, TrajectorySequence([tr, Hold(d.centres[0], _FOREVER, self.yaw, t_start=tr.t_end)]), bus)
        self._t_leg_end = tr.t_end
        self._enter(t, "enter", "", bus)

    def _plan_through(self, t: float, t_r: float, d: _Detections, bus: BusView) -> None:
        pp = self.params
        narrow = self._narrow(d)
        if narrow:
            self._abort(t, t_r, narrow, bus)
            return
        p = self.reference.sample(float(t_r)).p_W[0]
        n0 = d.normals[0] / np.linalg.norm(d.normals[0])
        _, after0 = self._axis_points(d, 0)
        pts = [p, p + (after0 - d.centres[0]) @ n0 * n0]
        for k in range(1, d.centres.shape[0]):
            before, after = self._axis_points(d, k)
            pts += [before, d.centres[k], after]
        nl = d.normals[-1] / np.linalg.norm(d.normals[-1])
        pts.append(d.centres[-1] + pp.exit_m * nl)
        rec = self._plan(t, t_r, "through", np.array(pts), d)
        if not rec.ok:
            back = self._align_point(self.used) if self.used is not None else None
            self._abort(t, t_r, f"no safe path through the frames: {rec.reason}", bus, back_W=back)
            return
        self.used = d
        self.progress = 1
        self._publish_leg(t, rec.trajectory, self.yaw, bus)
        self._enter(t, "through", "", bus)

    # -- stepwise: frame by frame (``through: stepwise``) -------------------------------------------------------
    def _update_stepwise(self, t: float, t_r: float, state: Odometry, est: TunnelEstimate | None, bus: BusView) -> None:
        """The states after take-off in stepwise mode: detect (the first frame) -> align (onto its axis) -> enter
        (the hop through it) -> wait (past it, for the next frame) -> through (the hop through that one) -> wait
        ... -> through (the last frame, on to ``exit_m`` beyond it) -> land."""
        pp = self.params
        if self.state == "detect":  # the first frame, confident and stable: fly onto its axis
            d = self._stable_next()
            if d is not None:
                self._align_stepwise(t, t_r, d, bus)
            elif t - self._t_state > pp.detect_timeout_s:
                self._abort(
                    t,
                    t_r,
                    f"frame 1 of {pp.frames} not detected, confident and stable in {pp.detect_timeout_s:g} s",
                    bus,
                )
            return
        if self.state == "align":  # on the first frame's axis: its newest stable detection, after hold_s there
            if t_r < self._t_leg_end + pp.hold_s:
                return
            d = self._stable_next()
            if d is not None:
                self._hop(t, t_r, d, bus)
            elif t_r - self._t_leg_end > pp.detect_timeout_s:
                self._abort(t, t_r, f"frame 1 of {pp.frames} not stable in {pp.detect_timeout_s:g} s", bus)
            return
        if self.state in ("enter", "through"):  # a hop through the target frame
            self._count_progress(state)
            if t_r < self._t_leg_end:
                return
            self._pass_target()
            if self._last_hop:
                self.progress = pp.frames
                self._land(t, t_r, self.reference.sample(float(t_r)).p_W[0], bus)
                self._enter(t, "land", "", bus)
                return
            k = self._n_passed()
            self._enter(t, "wait", f"for frame {k + 1} of {pp.frames}", bus)
            return
        if self.state == "wait":  # at rest past the last passed frame: the next one, confident and stable
            d = self._stable_next()
            if d is not None:
                self._hop(t, t_r, d, bus)
            elif t - self._t_state > pp.detect_timeout_s:
                k = self._n_passed()
                self._back_out(
                    t,
                    t_r,
                    f"frame {k + 1} of {pp.frames} not detected, confident and stable in {pp.detect_timeout_s:g} s "
                    f"past frame {k}",
                    bus,
                )

    def _n_passed(self) -> int:
        return 0 if self.passed is None else int(self.passed.centres.shape[0])

    def _pass_target(self) -> None:
        """The hop's frame is passed (the reference is at rest past it): it joins :attr:`passed`, once."""
        d = self._target
        if d is None:
            return
        self._target = None
        self.passed = d if self.passed is None else self.passed + d
        self.progress = max(self.progress, self._n_passed())

    def _next_in(self, est: TunnelEstimate) -> _Detections | None:
        """The frame the mission flies through next, as ``est`` has it: before the course, the estimate's first
        frame (the nearest the pad); past a frame, the detected frame nearest the last passed one among those at
        least ``next_min_m`` beyond its plane. None unless that frame is confident and at most ``max_gap_m`` from
        the last passed one (a nearer frame not yet confident is waited for, never flown through unchecked)."""
        if self.passed is None:
            return self._confident(est, 1)
        pp = self.params
        conf = np.asarray(est.confidence, dtype=float).reshape(-1)
        c = np.asarray(est.centres_W, dtype=float).reshape(-1, 3)
        n = np.asarray(est.normals_W, dtype=float).reshape(-1, 3)
        s = np.asarray(est.opening_sizes, dtype=float).reshape(-1, 2)
        c_l, n_l = self.passed.centres[-1], self.passed.normals[-1] / np.linalg.norm(self.passed.normals[-1])
        gap = np.linalg.norm(c - c_l, axis=1)
        ahead = (c - c_l) @ n_l >= pp.next_min_m
        if not ahead.any():
            return None
        k = int(np.argmin(np.where(ahead, gap, np.inf)))
        if conf[k] < pp.min_confidence or gap[k] > pp.max_gap_m:
            return None
        return _Detections(c[k : k + 1].copy(), n[k : k + 1].copy(), s[k : k + 1].copy())

    def _stable_next(self) -> _Detections | None:
        """The next frame (:meth:`_next_in`) when the newest ``stable_updates + 1`` estimates all hold it, each
        centre within ``stable_m`` of the one before; else None."""
        pp = self.params
        recent = self.detections[-(pp.stable_updates + 1) :]
        if len(recent) < pp.stable_updates + 1:
            return None
        picks = [self._next_in(e) for _, e in recent]
        if any(d is None for d in picks):
            return None
        cs = np.array([d.centres[0] for d in picks if d is not None])
        if float(np.max(np.linalg.norm(np.diff(cs, axis=0), axis=1))) >= pp.stable_m:
            return None
        return picks[-1]

    def _facing(self, d: _Detections, p: np.ndarray) -> tuple[_Detections, float]:
        """``d`` (one frame) with its normal horizontal, unit and pointing away from ``p`` (the way through), and
        its heading nearest :attr:`heading` [rad]."""
        n = np.array([d.normals[0, 0], d.normals[0, 1], 0.0])
        n = n / max(float(np.linalg.norm(n)), 1e-12)
        if float((d.centres[0] - p) @ n) < 0:
            n = -n
        psi = math.atan2(n[1], n[0])
        psi = self.heading + math.remainder(psi - self.heading, 2 * math.pi)
        return _Detections(d.centres.copy(), n[None, :], d.sizes.copy()), psi

    def _align_stepwise(self, t: float, t_r: float, d: _Detections, bus: BusView) -> None:
        """Onto the first frame's axis, ``align_m`` before it, turning to face along it (a min-snap leg checked
        against its bars)."""
        narrow = self._narrow(d)
        if narrow:
            self._abort(t, t_r, narrow, bus)
            return
        p = self.reference.sample(float(t_r)).p_W[0]
        d, psi = self._facing(d, p)
        goal = self._align_point(d)
        rec = self._plan(t, t_r, "align", np.array([p, goal]), d, yaw=np.array([self.heading, psi]))
        if not rec.ok:
            self._abort(t, t_r, f"no safe path onto the first frame's axis: {rec.reason}", bus)
            return
        self.used = d
        self._publish_leg(t, rec.trajectory, psi, bus)
        self._enter(t, "align", "", bus)

    def _publish_leg(self, t: float, tr: Any, psi: float, bus: BusView) -> None:
        """Fly ``tr``, then hold its end facing ``psi`` (the new :attr:`heading`) [rad]."""
        end = tr.sample(tr.t_end).p_W[0]
        self._publish(t, TrajectorySequence([tr, Hold(end, _FOREVER, psi, t_start=tr.t_end)]), bus)
        self.heading, self._t_leg_end = psi, tr.t_end

    def _hop(self, t: float, t_r: float, target: _Detections, bus: BusView) -> None:
        """From rest (at the align point, or past the last passed frame) through ``target``'s opening along its
        normal to a rest point on its axis past it (the last frame: ``exit_m`` beyond it), yawing to face along
        it; checked against the bars of every passed frame and the target. Never back through a passed frame."""
        pp = self.params
        k = self._n_passed()  # the target is frame k + 1
        inside = k > 0
        narrow = self._narrow(target)
        if narrow:
            msg = narrow.replace("opening 1", f"opening {k + 1}")
            (self._back_out if inside else self._abort)(t, t_r, msg, bus)
            return
        p = self.reference.sample(float(t_r)).p_W[0]
        target, psi = self._facing(target, p)
        d = target if self.passed is None else self.passed + target
        before, after = self._axis_points(d, k)
        c, n = target.centres[0], target.normals[0]
        ahead = float((p - c) @ n)  # < 0: before the frame
        via = [c + ahead * n] if not inside and ahead < float((before - c) @ n) - 0.05 else []
        last = k + 1 >= pp.frames
        pts = [p, *via, before, c, after] + ([c + pp.exit_m * n] if last else [])
        leg = "through" if inside else "enter"
        rec = self._plan(t, t_r, leg, np.array(pts), d, yaw=np.array([self.heading] + [psi] * (len(pts) - 1)))
        if not rec.ok:
            if inside:
                self._back_out(t, t_r, f"no safe path through frame {k + 1}: {rec.reason}", bus)
            else:
                self._abort(t, t_r, f"no safe path into the first frame: {rec.reason}", bus)
            return
        self._target, self.used, self._last_hop = target, d, last
        self._publish_leg(t, rec.trajectory, psi, bus)
        self._enter(t, leg, f"frame {k + 1} of {pp.frames}", bus)

    def _descent_clear(self, p: np.ndarray, d: _Detections) -> bool:
        """A straight descent from ``p`` to the pad's height keeps ``clearance`` from the bars of ``d``."""
        down = p + np.linspace(0.0, 1.0, 50)[:, None] * np.array([0.0, 0.0, float(self.pad_W[2]) - p[2]])
        return float(frame_boxes(d.centres, d.normals, d.sizes, self.params.bar).distance(down).min()) >= (
            self.params.clearance
        )

    def _back_out(self, t: float, t_r: float, reason: str, bus: BusView) -> None:
        """Abort from rest inside the course (past a frame): land where it is when the descent keeps ``clearance``
        from every passed frame's bars (the rest point is on the frame's axis past it, the rules put the next frame
        0.5 m or more beyond); else back out through the passed frames' openings (their axis points in reverse,
        the heading kept) to the first frame's align point and land there; if that path fails the plan check too,
        land where it is (and say so). Flown on VIO, a back-out through 0.5 m openings after a long hover met a
        bar: the estimate had drifted 14 cm across them."""
        d = self.passed
        if d is None:
            self._abort(t, t_r, reason, bus)
            return
        p = self.reference.sample(float(t_r)).p_W[0]
        if self._descent_clear(p, d):
            self._abort(t, t_r, reason, bus)
            return
        pts = [p]
        for j in reversed(range(d.centres.shape[0])):
            before, after = self._axis_points(d, j)
            pts += [after, d.centres[j], before]
        pts.append(self._align_point(d))
        rec = self._plan(t, t_r, "back_out", np.array(pts), d, yaw=np.full(len(pts), self.heading))
        if not rec.ok:
            self._abort(t, t_r, f"{reason}; no safe path back out ({rec.reason}): landed where it was", bus)
            return
        tr = rec.trajectory
        self._publish_leg(t, tr, self.heading, bus)
        self._land(t, tr.t_end, tr.sample(tr.t_end).p_W[0], bus)
        self._enter(t, "aborted", reason, bus)

    def _failsafe_stepwise(self, t: float, t_r: float, bus: BusView) -> None:
        """A failsafe's land request in stepwise mode: before the course as in ``all``; inside it, at rest past a
        frame, as a timeout there (:meth:`_back_out`; a hop is finished first unless the request is urgent)."""
        assert self._failsafe is not None
        reason = f"failsafe: {self._failsafe[1]}"
        hop = self.state in ("enter", "through")
        if hop and t_r < self._t_leg_end:
            if not self._failsafe_urgent:
                return  # the hop ends at rest past its frame: back out from there
            self._abort(t, t_r, reason, bus)  # urgent (e.g. a motor failure): land at once
            return
        if hop:
            self._pass_target()
        if self.passed is not None:
            self._back_out(t, t_r, reason, bus)
        else:
            self._abort(t, t_r, reason, bus)

    def start(self, t: float, pad_W: Any) -> None:
        """The operator's start (a mission built ``wait_for_start``, flown by a commander that samples
        :attr:`reference`): initialise ``init_s`` on the pad at ``pad_W`` (where the vehicle rests), then fly."""
        self.pad_W = np.asarray(pad_W, dtype=float)
        self.reference = self.initial = Hold(self.pad_W, _FOREVER, self.yaw, t_start=float(t))
        self.t_go, self.reason = float(t), ""

    def stop(self, t: float, reason: str) -> None:
        """The operator took over (under a commander): the state machine ends here and publishes no more plans."""
        if not self.finished:
            self.state, self.reason, self._t_state = "aborted", reason, t
            self.transitions.append((t, "aborted", reason))

    def step(self, t: float, bus: BusView) -> None:
        if self.t_go is None:  # waiting for the operator's start
            bus.publish(Topics.MISSION_STATE, MissionState(t, self.state, self.reason, self.progress))
            return
        state = bus.latest(self.active_state_topic)
        if state is None:
            if self.state == "initialise" and t >= self.params.init_s + 5.0:
                self._abort(t, t + self.latency_s, "no state estimate after initialisation", bus)
            return
        if t - float(state.t) > self.params.stale_s and self.state not in ("done", "aborted"):
            self._abort(t, t + self.latency_s, f"state estimate stale ({t - float(state.t):.2f} s old)", bus)
            return
        self.update(t, state, bus)
        bus.publish(Topics.MISSION_STATE, MissionState(t, self.state, self.reason, self.progress))


__all__ += ["PlanRecord"]

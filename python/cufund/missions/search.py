"""The ``search`` mission kind: find the people in an area. Take off, fly a boustrophedon coverage of the area
(:func:`cufund.missions.coverage.plan_coverage`) at a fixed altitude facing along each leg (a forward camera
pitched down sweeps the ground ahead), come back and land; meanwhile the detections of people in the world frame
(``Detections3D`` of the scenario's perception, e.g. ``onnx_detector`` with a depth camera or a stereo pair) are
associated into tracks and confirmed from two views (:mod:`.search_tracks`). The confirmed positions go to
``found_people.json`` in the run folder; the metrics compare them with the people placed in the world (read by
the metric alone)."""

from __future__ import annotations

import json
import math
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.components import BusView, Component, Subscription
from cufund.core.config import ConfigError, check_real_fields, nested
from cufund.core.messages import Detections3D, Topics
from cufund.core.registry import Kind, register
from cufund.perception.pose_history import PoseHistory
from cufund.planning.point_to_point import JerkLimitedMove
from cufund.planning.sequence import Hold, TrajectorySequence
from cufund.planning.trajectory import TrajectorySamples
from cufund.planning.trajectory_follower import TrajectoryFollower

from .coverage import plan_coverage
from .fleet_polygon import check_polygon, polygon_contains
from .search_tracks import SearchTracker, SearchTrackParams, search_metrics

__all__ = ["SearchMission", "SearchParams", "StraightMove", "search_reference"]

_POSES_KEPT = 400
"""Estimates kept to find the camera's position at a detection's capture time (2 s at 200 Hz)."""


@dataclass(frozen=True)
class SearchParams:
    """Where and how to search. Lengths [m], speeds [m/s], times [s]."""

    area: tuple[tuple[float, float], ...] = ((-16.0, -16.0), (16.0, -16.0), (16.0, 16.0), (-16.0, 16.0))
    """The polygon searched ((x, y), ...) [m]: the lanes cover it, and detections placed outside it (farther than
    ``area_margin_m``) are ignored."""
    lead_m: float = 0.0
    """Each lane runs this far beyond the area at both ends [m]: a forward camera pitched down sees the ground from
    some metres ahead of the vehicle, so a lane that starts at the area's edge would miss the strip behind it."""
    area_margin_m: float = 1.0
    """Detections up to this far outside the area still count [m]."""
    altitude: float = 12.0
    """Flight altitude above the start (above the trees) [m]."""
    spacing: float = 8.0
    """Distance between coverage lanes [m]."""
    heading: float | None = None
    """Lane direction [rad, ENU from east]; null: along the area's longest edge."""
    v_max: float = 3.0
    """Speed limit along the legs [m/s]."""
    a_max: float = 2.0
    """Acceleration limit [m/s^2]."""
    j_max: float = 5.0
    """Jerk limit [m/s^3]."""
    climb_v_max: float = 1.5
    """Take-off and landing speed limit [m/s]."""
    yaw_rate: float = 0.8
    """Peak yaw rate of the turns between legs [rad/s]."""
    target: str = "person"
    """The class searched for (a name of the detector's model)."""
    max_height_m: float = 1.6
    """Detections placed higher than this above the take-off point are ignored [m]: people stand or lie on the
    ground (a flat area is assumed; a standing person's box centre is about 0.9 m up), while a box whose middle
    shows a trunk in front of the person is placed on the trunk, nearer and so higher along the ray."""
    min_height_m: float = -0.5
    """Detections placed lower than this (below the ground) are ignored [m]."""
    max_box_m: float | None = None
    """Detections whose box, at its depth, is taller or wider than this are ignored [m] (null: no limit): a
    person (at most about 2 m tall, seen from above at a slant, or lying) spans well under this in the image
    plane, while a patch of ground or a trunk the detector takes for one often spans more."""
    tracks: SearchTrackParams = SearchTrackParams()
    """Association and two-view confirmation (:class:`~cufund.missions.search_tracks.SearchTrackParams`)."""
    match_m: float = 2.0
    """Metric only: a find counts if within this of a person placed [m]."""

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "area", tuple(tuple(float(c) for c in v) for v in check_polygon(self.area)))
        except (TypeError, ValueError) as e:
            raise ConfigError(f"mission.area: {e}") from None
        names = ("altitude", "spacing", "v_max", "a_max", "j_max", "climb_v_max", "yaw_rate", "match_m", "max_height_m")
        check_real_fields(self, "mission", positive=True, names=names)
        check_real_fields(self, "mission", unit=" [m]", names=("lead_m", "area_margin_m"))
        if self.max_box_m is not None:
            check_real_fields(self, "mission", positive=True, names=("max_box_m",))
        v = self.min_height_m
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not -1e3 < v < self.max_height_m:
            raise ConfigError(f"mission.min_height_m must be a number below max_height_m [m], got {v!r}")
        h = self.heading
        if h is not None and (isinstance(h, bool) or not isinstance(h, (int, float)) or not math.isfinite(h)):
            raise ConfigError(f"mission.heading must be an angle [rad] or null, got {h!r}")
        if not isinstance(self.target, str) or not self.target:
            raise ConfigError(f"mission.target must be a class name, got {self.target!r}")
        try:
            object.__setattr__(self, "tracks", nested(SearchTrackParams, self.tracks, "mission.tracks"))
        except ValueError as e:
            raise ConfigError(f"mission.tracks: {e}") from None


class StraightMove:
    """A jerk-limited move from ``start_W`` to ``goal_W`` [m] along the straight line between them (ruckig's
    per-axis time-optimal move would bend a diagonal), at rest at both ends, holding ``yaw`` [rad]; the limits
    apply along the line."""

    def __init__(
        self,
        start_W: np.ndarray,
        goal_W: np.ndarray,
        v_max: float,
        a_max: float,
        j_max: float,
        yaw: float,
        t_start: float,
    ) -> None:
        self.a = np.asarray(start_W, dtype=float)
        d = np.asarray(goal_W, dtype=float) - self.a
        length = float(np.linalg.norm(d))
        self.u = d / length if length > 0 else np.zeros(3)
        self._move = JerkLimitedMove(np.zeros(3), np.array([length, 0.0, 0.0]), v_max, a_max, j_max, yaw, t_start)
        self.t_start = float(t_start)

    @property
    def duration(self) -> float:
        return float(self._move.duration)

    @property
    def t_end(self) -> float:
        return float(self._move.t_end)

    def sample(self, t: np.ndarray | float) -> TrajectorySamples:
        s = self._move.sample(t)
        u = self.u[None, :]
        return TrajectorySamples(
            t=s.t,
            p_W=self.a + s.p_W[:, :1] * u,
            v_W=s.v_W[:, :1] * u,
            a_W=s.a_W[:, :1] * u,
            j_W=s.j_W[:, :1] * u,
            yaw=s.yaw,
            yaw_rate=s.yaw_rate,
        )


def search_reference(
    p: SearchParams, start_W: np.ndarray, yaw0: float = 0.0
) -> tuple[TrajectorySequence, np.ndarray, tuple[float, float]]:
    """The search's reference: climb to ``altitude`` above ``start_W``, then each leg of the coverage path, its
    lanes ``lead_m`` longer at both ends (turn to face along it, fly it, stop), back above the start, land. Returns
    (reference, coverage waypoints (n, 3), (t0, t1): when the coverage starts, at altitude, and ends [s])."""
    start = np.asarray(start_W, dtype=float)
    try:
        cell = plan_coverage(p.area, {"search": start}, p.spacing, p.altitude, heading=p.heading, max_lanes=1000)
    except ValueError as e:
        raise ConfigError(f"mission: {e}") from None
    path = np.array(cell["search"].path, dtype=float)
    path[:, 2] = start[2] + p.altitude
    for k in range(0, len(path) - 1, 2):  # each lane (piece) is a pair of waypoints: run it lead_m longer at both ends
        d = path[k + 1] - path[k]
        u = d / max(float(np.linalg.norm(d)), 1e-9)
        path[k] -= p.lead_m * u
        path[k + 1] += p.lead_m * u
    top = start + np.array([0.0, 0.0, p.altitude])
    parts: list[Any] = []
    t, yaw, here = 0.0, float(yaw0), start
    legs = [(top, p.climb_v_max), *((w, p.v_max) for w in path), (top, p.v_max), (start, p.climb_v_max)]
    window = [0.0, 0.0]
    for k, (goal, v) in enumerate(legs):
        if k == 2:  # the first lane begins (after the climb and the transit to its start)
            window[0] = t
        d = goal - here
        if np.linalg.norm(d[:2]) > 1e-6:  # a horizontal leg: face along it first
            heading = math.atan2(d[1], d[0])
            if abs(math.remainder(heading - yaw, 2 * math.pi)) > 1e-6:
                parts.append(Hold.turn(here, yaw, heading, p.yaw_rate, t_start=t))
                t, yaw = parts[-1].t_end, yaw + math.remainder(heading - yaw, 2 * math.pi)
        if np.linalg.norm(d) > 1e-6:
            parts.append(StraightMove(here, goal, v, p.a_max, p.j_max, yaw, t_start=t))
            t, here = parts[-1].t_end, goal
        if v == p.climb_v_max and goal is top:
            parts.append(Hold(here, 1.0, yaw, t_start=t))
            t = parts[-1].t_end
        if k == len(path):  # at the end of the last lane
            window[1] = t
    return TrajectorySequence(parts), path, (window[0], window[1])


class SearchMission(Component):
    """Flight software: each ``Detections3D`` of class ``target`` (scored at least ``tracks.min_score``, placed
    between ``min_height_m`` and ``max_height_m`` above ``ground_z``, the take-off point's height, and inside the
    area or within ``area_margin_m`` of it, captured while the lanes are flown: within ``window`` [s]) goes to the
    :class:`~cufund.missions.search_tracks.SearchTracker` with the camera's position at its capture time taken
    from the estimate (the body's position; the camera sits centimetres from it)."""

    name = "search_mission"

    def __init__(
        self,
        params: SearchParams,
        ground_z: float = 0.0,
        window: tuple[float, float] = (0.0, math.inf),
        state_topic: str = Topics.ESTIMATE,
        rate_hz: float = 20.0,
    ) -> None:
        self.params = params
        self.ground_z = float(ground_z)
        self.window = (float(window[0]), float(window[1]))
        self.state_topic = state_topic
        self.rate_hz = float(rate_hz)
        self.inputs = (Topics.DETECTIONS_3D, state_topic)
        self.outputs = ()
        self.reset()

    def reset(self) -> None:
        self.tracker = SearchTracker(self.params.tracks)
        self._poses = PoseHistory(maxlen=_POSES_KEPT)
        self._pending: deque[Detections3D] = deque(maxlen=64)
        self.detections = 0

    def setup(self, bus: BusView) -> None:
        self._dets: Subscription = bus.subscribe(Topics.DETECTIONS_3D)
        self._states: Subscription = bus.subscribe(self.state_topic)

    def step(self, t: float, bus: BusView) -> None:
        self._poses.extend(self._states.take())
        self._pending.extend(self._dets.take())
        t_last = self._poses.t_last
        while self._pending and t_last is not None and self._pending[0].t <= t_last:
            msg = self._pending.popleft()
            if not self.window[0] <= msg.t <= self.window[1]:
                continue  # climbing, in transit to the first lane, going home or landing: not searching
            camera = self._poses.position_at(msg.t)
            if camera is None:
                continue
            names = tuple(msg.class_names)
            if self.params.target not in names:
                continue
            k = names.index(self.params.target)
            box_max = self.params.max_box_m if self.params.max_box_m is not None else math.inf
            for p_W, size, cls, score in zip(msg.centres_W, msg.sizes_m, msg.class_ids, msg.scores, strict=True):
                if (
                    int(cls) == k
                    and float(score) >= self.params.tracks.min_score
                    and float(np.max(size)) <= box_max
                    and np.all(np.isfinite(p_W))
                    and self.params.min_height_m <= p_W[2] - self.ground_z <= self.params.max_height_m
                    and polygon_contains(self.params.area, p_W[:2], tol=self.params.area_margin_m)[0]
                ):
                    self.tracker.add(msg.t, p_W, camera, float(score))
                    self.detections += 1

    def found(self) -> list[dict[str, Any]]:
        """The confirmed finds: position [m], when confirmed [s], detections merged."""
        out = []
        found = self.tracker.found()
        confirmed = self.tracker.confirmed()
        for p in found:
            near = [k for k in confirmed if np.linalg.norm(k.mean - p) <= self.params.tracks.gate_m]
            out.append(
                {
                    "p_W": [round(float(x), 4) for x in p],
                    "confirmed_at_s": round(min(float(k.confirmed_at) for k in near), 3) if near else None,  # type: ignore[arg-type]
                    "detections": int(sum(len(k.positions) for k in near)),
                }
            )
        return out


def _search(p: SearchParams, ctx: BuildContext) -> list[Any]:
    from cufund.worlds.search_forest import people_positions

    cfg = ctx.config
    if cfg.estimator is None:
        raise ConfigError(
            "mission (search) flies on an estimate: set estimator (e.g. estimator: {kind: imu_propagator})"
        )
    if cfg.perception is None:
        raise ConfigError(
            "mission (search) needs detections in the world: set perception (e.g. onnx_detector with a depth camera or a stereo pair)"
        )
    if cfg.planner is not None:  # its follower would publish trajectory setpoints beside the mission's own
        raise ConfigError("mission (search) flies its own reference: set planner: null")
    start = np.array(cfg.start_p_W if cfg.start_p_W is not None else (0.0, 0.0, 0.0), dtype=float)
    reference, path, window = search_reference(p, start, float(cfg.start_yaw or 0.0))
    follower = TrajectoryFollower(reference, rate_hz=cfg.rates.trajectory_hz)
    ctx.set_reference(reference)
    mission = SearchMission(p, ground_z=float(start[2]), window=window)

    def metrics(result: Any) -> dict[str, Any]:
        world = ctx.truth_world_for_metrics()  # the metric's alone (after the run): the mission never sees it
        people = people_positions(world) if world is not None else np.zeros((0, 3))
        found = mission.found()
        times = [f["confirmed_at_s"] for f in found if f["confirmed_at_s"] is not None]
        m = search_metrics(
            np.array([f["p_W"] for f in found]).reshape(-1, 3), people, p.match_m, max(times) if times else None
        )
        m["search_people"] = len(people)
        m["search_finds"] = len(found)
        m["search_detections"] = mission.detections
        m["search_tracks"] = len(mission.tracker.tracks)
        return m

    def write(run: Any, out: Any, **kw: Any) -> None:
        doc = {"frame": "world ENU", "unit": "m", "found": mission.found(), "coverage_W": path.round(3).tolist()}
        (Path(out) / "found_people.json").write_text(json.dumps(doc, indent=1) + "\n")

    ctx.add_metric_hook(metrics)
    ctx.add_output_hook(write)
    return [mission, follower]


register(
    Kind(
        "mission",
        "search",
        SearchParams,
        _search,
        None,
        "fly a coverage of an area, confirm each person detected from two views, write found_people.json",
    )
)

"""What the ground station knows about one live run: its scene, the flown path, recent telemetry, the event log,
the latest LiDAR cloud and ESDF slice, the gates the vehicle detected — all as JSON-able values for the page (and
for tabs that reconnect).

The gates (a tunnel course's frames) are the vehicle's: what its detector published last on
``Topics.TUNNEL_ESTIMATE``, in its estimated world frame, updated as frames are found; they are the mission
regions ``gate1`` .. ``gateK`` the page may name. The true course is never shown or offered: where the run detects
gates, the world's ``tunnel_frame`` meshes are left out of the scene (the arena's floor and walls stay, as the
surveyed room a ground station knows); the world drawn is the simulation's, marked ``world_truth``.

A :class:`GcsSession` wraps one :class:`cufund.apps.live.LiveRun`. Every method except the ESDF sampler (which the
live run calls from its simulation thread, between steps, where reading the mapper's map is safe) runs on the
server's event-loop thread.
"""

from __future__ import annotations

import base64
import collections
import contextlib
import dataclasses
import enum
import math
import time
from typing import Any

import numpy as np

from cufund.core.messages import Topics, TunnelEstimate, VioDiagnostics
from cufund.geometry import quat_to_matrix
from cufund.planning.mission_spec import Region

__all__ = ["GcsSession", "jsonable", "position_of"]

MAX_CLOUD_POINTS = 8000
"""Points of a LiDAR frame sent to the page (a deterministic stride through the frame)."""
HISTORY_S = 30.0
"""Telemetry kept for a tab that (re)connects [s of simulated time]."""
PATH_STEP_M = 0.02
"""The flown path keeps a point when the vehicle moved this far [m]."""
ESDF_CELLS = 64
"""ESDF slice resolution (cells per side)."""
GROUND_SLICE_M = 1.0
"""Height of the ESDF slice while the vehicle is below it [m]."""
GATE_REGION_RADIUS_M = 0.2
"""Radius of the mission region around a detected gate's centre [m]."""
COURSE_LABEL = "tunnel_frame"
"""Label of the world's meshes that make up a tunnel course's frames (withheld while the vehicle detects them)."""


def jsonable(value: Any) -> Any:
    """``value`` with numpy arrays and scalars, enums, dataclasses and non-finite floats made JSON-safe."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, enum.Enum):
        return str(value.name).lower()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return jsonable({f.name: getattr(value, f.name) for f in dataclasses.fields(value)})
    if value is None or isinstance(value, (str, bool, int)):
        return value
    return str(value)


def position_of(telemetry: dict[str, Any]) -> np.ndarray | None:
    p = telemetry.get("p_W")
    if p is None:
        return None
    a = np.asarray(p, dtype=float)
    return a if a.shape == (3,) and np.all(np.isfinite(a)) else None


def _world_of(live: Any) -> tuple[Any, bool]:
    """The simulation's :class:`cufund.worlds.World` (the truth, drawn as the simulated room) and whether the run
    detects gates (something publishes ``Topics.TUNNEL_ESTIMATE``)."""
    built = getattr(live, "built", None)
    context = getattr(built, "context", None)
    accessor = getattr(context, "truth_world_for_metrics", None)
    world = accessor() if callable(accessor) else getattr(context, "world", None)
    components = getattr(getattr(built, "simulator", None), "components", None) or ()
    detects = any(str(Topics.TUNNEL_ESTIMATE) in {str(t) for t in c.outputs} for c in components)
    return world, detects


def gates_of(estimate: TunnelEstimate | None) -> list[dict[str, Any]]:
    """The gates of a detector's estimate, in its (estimated) world frame and flying order: ``name`` (``gate1``
    ..), ``centre_W``, ``normal_W``, ``size`` (width, height) [m] and ``confidence``."""
    if estimate is None:
        return []
    return [
        {
            "name": f"gate{k + 1}",
            "centre_W": [round(float(v), 3) for v in estimate.centres_W[k]],  # mm: a change below is not news
            "normal_W": [round(float(v), 3) for v in estimate.normals_W[k]],
            "size": [round(float(v), 3) for v in estimate.opening_sizes[k]],
            "confidence": round(float(estimate.confidence[k]), 2),
        }
        for k in range(len(estimate.centres_W))
        if np.all(np.isfinite(estimate.centres_W[k]))
    ]


def _mission_count(config: Any) -> int | None:
    """How many steps a scenario's own mission counts its progress in (the tunnel's frames), or None."""
    params = getattr(getattr(config, "mission", None), "params", None)
    frames = getattr(params, "frames", None)
    return int(frames) if isinstance(frames, int) else None


def _config_of(live: Any) -> Any:
    config = getattr(live, "config", None)
    if config is None:
        config = getattr(getattr(live, "built", None), "config", None)
    return config


class GcsSession:
    """The ground station's view of one live run (see the module docstring)."""

    def __init__(self, live: Any, scenario: str) -> None:
        self.live = live
        self.scenario = scenario
        self.started_wall = time.time()
        self.world, self.detects_gates = _world_of(live)
        self.config = _config_of(live)
        self.gates: list[dict[str, Any]] = []
        """The gates detected so far (see :func:`gates_of`)."""
        self._gates_key: Any = None
        self.path: list[list[float]] = []
        self.history: collections.deque[dict[str, Any]] = collections.deque()
        self.events: list[dict[str, Any]] = []
        self._events_seen = 0
        self._mission_state: tuple[str, str] | None = None
        self.planned: list[list[float]] = []
        self.planned_label = ""
        self.planned_changed = False
        """Set when a new plan replaced the drawn one (the server then sends it to every tab)."""
        self._plan_seen: list[Any] = []
        self.telemetry: dict[str, Any] = {}
        self._last_t = -math.inf
        self._cloud_key: Any = None
        self.cloud: bytes | None = None
        self.esdf: dict[str, Any] | None = None
        self._esdf_key: Any = None
        self.T_BL = self._lidar_mount()
        self.capabilities: dict[str, Any] = {}
        """What the scenario supports (set by the server: :func:`cufund.apps.gcs.server.capabilities`)."""
        self.mission_count = _mission_count(self.config)

    # ---- static scene --------------------------------------------------------------------------------------
    def scene(self) -> dict[str, Any]:
        """World meshes, vehicle size and mission regions: sent once to every tab that connects."""
        meshes = []
        if self.world is not None:
            for obj in self.world.objects:
                if self.detects_gates and obj.label == COURSE_LABEL:
                    continue  # the true course: the page shows the gates the vehicle detected instead
                meshes.append(
                    {
                        "label": obj.label,
                        "color": list(obj.color),
                        "vertices": np.round(np.asarray(obj.vertices, dtype=float), 4).ravel().tolist(),
                        "triangles": np.asarray(obj.triangles, dtype=int).ravel().tolist(),
                    }
                )
        arm = 0.15
        with contextlib.suppress(Exception):  # a config without a vehicle: the default size
            arm = float(self.config.vehicle_params().arm_length)
        return {
            "scenario": self.scenario,
            "meshes": meshes,
            "world_truth": True,
            "arm_length": arm,
            "regions": [jsonable(r) for r in self.regions()],
            "gates": self.gates,
        }

    def regions(self) -> list[Region]:
        """The mission regions the page may name: the gates detected so far (``gate1`` ..), spheres of
        :data:`GATE_REGION_RADIUS_M` at their estimated centres."""
        return [Region(g["name"], tuple(g["centre_W"]), radius=GATE_REGION_RADIUS_M) for g in self.gates]

    def new_gates(self) -> dict[str, Any] | None:
        """The detector's latest estimate as a ``gates`` message when it changed since the last call, else None."""
        est = self.live.latest(Topics.TUNNEL_ESTIMATE)
        if est is None:
            return None
        key = (est.t, est.scans, id(est))
        if key == self._gates_key:
            return None
        self._gates_key = key
        gates = gates_of(est)
        if gates == self.gates:
            return None
        self.gates = gates
        return {"type": "gates", "t": float(est.t), "frame": "estimated", "gates": gates}

    def _lidar_mount(self) -> tuple[np.ndarray, np.ndarray]:
        for spec in (getattr(self.config, "sensors", None) or {}).values():
            if str(getattr(spec, "topic", "")) == Topics.POINT_CLOUD and getattr(spec, "extrinsic", None) is not None:
                return np.array(spec.extrinsic.t, dtype=float), quat_to_matrix(np.array(spec.extrinsic.q, float))
        return np.zeros(3), np.eye(3)

    # ---- live state ----------------------------------------------------------------------------------------
    def poll(self) -> dict[str, Any]:
        """Reads the run's telemetry; extends the flown path and the history. Returns the telemetry."""
        tel = jsonable(self.live.telemetry())
        diag = self.live.latest(Topics.ESTIMATOR_DIAGNOSTICS)  # an odometry's word on its newest frame
        if diag is not None and isinstance(tel.get("estimator"), dict) and isinstance(tel.get("t"), (int, float)):
            vio = isinstance(diag, VioDiagnostics)  # a visual-inertial one's stereo frame, else a LiDAR scan
            tel["estimator"]["vision" if vio else "lidar"] = {
                "healthy": bool(diag.healthy),
                "reason": str(diag.reason),
                "age_s": round(float(tel["t"]) - float(diag.t), 3),
                "inliers": int(diag.inliers),
                ("tracked" if vio else "points"): int(diag.tracked if vio else diag.points),
                "skipped": str(diag.skipped),
            }
        state = self.live.latest(Topics.MISSION_STATE)  # a scenario's own mission (the tunnel's state machine)
        if state is not None:
            tel["mission_state"] = {
                "state": str(state.state),
                "reason": str(state.reason),
                "progress": int(state.progress),
                "count": self.mission_count,
            }
        self.telemetry = tel
        t = tel.get("t")
        p = position_of(tel)
        if p is not None and (not self.path or np.linalg.norm(p - np.asarray(self.path[-1])) >= PATH_STEP_M):
            self.path.append([round(float(v), 4) for v in p])
            if len(self.path) > 20000:
                del self.path[: len(self.path) - 20000]
        self._follow_plan(tel, p)
        if isinstance(t, (int, float)) and t >= self._last_t + 0.05:
            self._last_t = t
            self.history.append(tel)
            while self.history and self.history[0].get("t", t) < t - HISTORY_S:
                self.history.popleft()
        return tel

    def _follow_plan(self, tel: dict[str, Any], p: np.ndarray | None) -> None:
        """The commander's targets still to fly (``plan_W``): a new plan is drawn from where the vehicle is; one
        that only lost its reached targets leaves the drawn path alone (the flown path shows the progress)."""
        plan = tel.get("plan_W")
        if not isinstance(plan, list):
            return
        prev, self._plan_seen = self._plan_seen, plan
        progressed = len(plan) <= len(prev) and plan == prev[len(prev) - len(plan) :]
        if plan and not progressed:
            self.set_planned(([] if p is None else [p.tolist()]) + plan, str(tel.get("mode", "")))
            self.planned_changed = True

    def new_events(self) -> list[dict[str, Any]]:
        """Events of the run not yet seen (each also kept for tabs that connect later)."""
        fresh = [self._event(e) for e in self.live.events.since(self._events_seen)]
        if fresh:
            self._events_seen = int(fresh[-1].get("index", self._events_seen + len(fresh) - 1)) + 1
        state = self.live.latest(Topics.MISSION_STATE)  # a mission component's (e.g. the tunnel's) transitions
        if state is not None and (state.state, state.reason) != self._mission_state:
            self._mission_state = (state.state, state.reason)
            fresh.append(
                {
                    "t": float(state.t),
                    "kind": "mission",
                    "message": f"mission {state.state}"
                    + (f": {state.reason}" if state.reason else "")
                    + f" ({state.progress} done)",
                }
            )
        return [self.log(e) for e in fresh]

    def log(self, event: dict[str, Any]) -> dict[str, Any]:
        self.events.append(event)
        if len(self.events) > 2000:
            del self.events[:500]
        return event

    @staticmethod
    def _event(e: Any) -> dict[str, Any]:
        d = jsonable(e)
        if not isinstance(d, dict):
            d = {"message": str(d)}
        return d

    def catch_up(self) -> dict[str, Any]:
        """Everything a tab needs to draw the present: the scene, the flown and planned paths, recent telemetry
        for the plots, the event log, the ESDF slice."""
        return {
            "type": "hello",
            "scene": self.scene(),
            "path": self.path,
            "planned": self.planned,
            "planned_label": self.planned_label,
            "history": list(self.history),
            "events": self.events[-300:],
            "esdf": self.esdf,
            "telemetry": self.telemetry,
            "capabilities": self.capabilities,
        }

    def set_planned(self, points: Any, label: str) -> dict[str, Any]:
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        self.planned = np.round(pts, 4).tolist()
        self.planned_label = label
        return {"type": "planned", "planned": self.planned, "planned_label": label}

    # ---- sensor layers -------------------------------------------------------------------------------------
    def new_cloud(self) -> bytes | None:
        """The newest LiDAR frame in the world frame as little-endian float32 ``[t, n, x0, y0, z0, ...]``
        (at most :data:`MAX_CLOUD_POINTS` points), or None when no new frame came. The measured points, placed with
        the stated mounting and the vehicle's reported pose (what a ground station has; motion not undone): never
        the simulator's true hits."""
        msg = self.live.latest(Topics.POINT_CLOUD)
        if msg is None:
            return None
        key = (msg.t, id(msg))
        if key == self._cloud_key:
            return None
        self._cloud_key = key
        tel = self.telemetry
        p, q = position_of(tel), tel.get("q_WB")
        if p is None or q is None:
            return None
        R_WB = quat_to_matrix(np.asarray(q, dtype=float))
        p_BL, R_BL = self.T_BL
        pts = (np.asarray(msg.points_L, float) @ (R_WB @ R_BL).T + (R_WB @ p_BL + p)).astype(np.float32)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts) > MAX_CLOUD_POINTS:
            pts = pts[:: math.ceil(len(pts) / MAX_CLOUD_POINTS)]
        head = np.array([msg.t, len(pts)], dtype=np.float32)
        self.cloud = head.tobytes() + np.ascontiguousarray(pts, dtype="<f4").tobytes()
        return self.cloud

    def sample_esdf(self, *_: Any) -> None:
        """Samples the mapper's distance field on a horizontal slice at the vehicle's height (:data:`GROUND_SLICE_M`
        while it is lower: a slice through the floor shows nothing) — called by the live run in its simulation
        thread, where the map is not being updated."""
        msg = self.live.latest(Topics.ESDF_MAP)
        if msg is None or msg.map is None or (msg.t, msg.frames) == self._esdf_key:
            return
        self._esdf_key = (msg.t, msg.frames)
        esdf = msg.map
        params = esdf.params
        lo = np.asarray(params.origin_W, dtype=float)
        hi = lo + np.asarray(params.size, dtype=float)
        p = position_of(self.telemetry)
        z = float(np.clip(p[2] if p is not None and p[2] > GROUND_SLICE_M else GROUND_SLICE_M, lo[2], hi[2]))
        xs = np.linspace(lo[0], hi[0], ESDF_CELLS)
        ys = np.linspace(lo[1], hi[1], ESDF_CELLS)
        X, Y = np.meshgrid(xs, ys, indexing="xy")
        q = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, z)])
        d = np.asarray(esdf.distance(q), dtype=float).reshape(ESDF_CELLS, ESDF_CELLS)
        d = np.where(np.isfinite(d), d, 99.0)
        self.esdf = {
            "type": "esdf",
            "t": float(msg.t),
            "z": z,
            "x": [float(lo[0]), float(hi[0])],
            "y": [float(lo[1]), float(hi[1])],
            "n": ESDF_CELLS,
            "d": base64.b64encode(np.clip(d, -5, 5).astype("<f4").tobytes()).decode(),
        }

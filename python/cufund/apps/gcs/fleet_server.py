"""The ground station of a fleet (``cufund gcs FLEET_SCENARIO``): a live fleet (:class:`LiveFleet`) and one page
showing every vehicle on a top-down map in its own colour, with per-vehicle and all-vehicle commands and a mission
box that takes plain language (:func:`cufund.missions.parse_mission`), shows the mission it understood on the map,
and flies it only after that preview (docs/guides/fleet-gcs.md).

Routes (each needs the token and a ``Host`` naming this server; a POST from another site's ``Origin`` is refused:
the single-vehicle station's guard, :mod:`cufund.apps.gcs.guard`):

- ``GET /`` the page (``static/fleet.html``, ``static/fleet.js``).
- ``GET /api/state``: ``{"t", "paused", "ended", "names", "colours", "vehicles": {name: telemetry}, "events",
  "preview"}``; each vehicle's telemetry is :meth:`LiveRun.telemetry`'s flight state (position, velocity,
  attitude, armed, mode, mission progress, home, battery) without the truth.
- ``POST /api/command`` ``{"command": {...}, "vehicles": [names] | "all"}`` -> ``{"command", "acks": {name: ack}}``:
  the command to each vehicle named, each vehicle's commander answering for itself (an unknown vehicle is a 400).
  ``{"command": {"command": "sim_pause" | "sim_resume"}}`` pauses or resumes the whole fleet; ``start`` starts a
  fleet held for it (one with a mission of its own, e.g. ``fleet_survey``, waits at its first instant for it unless
  ``autostart``).
- ``POST /api/mission/preview`` ``{"text", "vehicles"?, "area"?}`` -> ``{"ok": true, "id", "summary",
  "mission", "waypoints": {name: [[x, y, z], ...]}}`` or ``{"ok": false, "reason"}`` (the request refused, with
  the reason: malformed, unsafe, an unknown vehicle, free text and no chat endpoint).
- ``POST /api/mission/fly`` ``{"id"}`` -> the acks of each vehicle's commands (arm when disarmed, then the
  mission's ``mission_upload`` and ``mission_start``, or its return): only the mission last previewed, by its id;
  anything else is refused with the reason ("preview it first").

Colours: vehicle ``i`` is :data:`FLEET_COLOURS` ``[i % 10]`` (matplotlib's tab10), on the map, the list and the
preview alike.
"""

from __future__ import annotations

import asyncio
import collections
import itertools
import secrets
import threading
from pathlib import Path
from typing import Any

import tornado.web

from .guard import listen, loads_strict
from .server import STATIC_DIR, _Guarded, parse_speed
from .session import jsonable

__all__ = ["FLEET_COLOURS", "FleetGcsServer", "fleet_server_for", "fleet_with_commanders"]

FLEET_COLOURS = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#9467bd",
    "#ff7f0e",
    "#17becf",
    "#e377c2",
    "#8c564b",
    "#bcbd22",
    "#7f7f7f",
)
"""Vehicle i's colour: ``FLEET_COLOURS[i % 10]`` (matplotlib's tab10)."""
ACK_TIMEOUT_S = 3.0
HELD_AT_S = 0.01
"""Where a fleet held for Start waits [s of simulated time]: past its first instant, so that it has telemetry."""
"""How long a command waits for a commander's acknowledgement before its reply says ``in_progress``."""
_FLIGHT_KEYS = (
    "t",
    "mode",
    "armed",
    "landed",
    "flight_mode",
    "home_p_W",
    "target_p_W",
    "mission",
    "message",
    "p_W",
    "v_W",
    "rpy",
    "battery",
    "estimator",
)
"""What the page gets of each vehicle's telemetry (the vehicle's belief, not the truth)."""
MAX_EVENTS = 200


def fleet_with_commanders(config: Any) -> Any:
    """``config`` (a fleet) with a commander where the scenario's own trajectory would fly by itself: the
    top-level planner becomes ``commander`` when it is none or the trajectory's ``waypoints`` follower
    (``fleet_square``'s squares: the vehicles wait for the operator, who flies them from the page); a vehicle's
    own planner is kept."""
    planner = getattr(config, "planner", None)
    if planner is None or planner.kind == "waypoints":
        return config.with_overrides({"planner": {"kind": "commander"}})
    return config


def fleet_server_for(
    scenario: str,
    overrides: tuple[str, ...],
    speed: float,
    host: str,
    port: int,
    port_fallback: bool,
    autostart: bool = False,
) -> FleetGcsServer | None:
    """The fleet station for ``scenario`` when it is a fleet (``vehicles:``), else None (the single-vehicle one)."""
    config = _station_config(scenario, overrides)
    if config is None:
        return None
    return FleetGcsServer(config, speed=speed, host=host, port=port, port_fallback=port_fallback, autostart=autostart)


def _station_config(scenario: str | Path, overrides: Any) -> Any:
    """The scenario ``scenario`` as the station flies it: with its commanders (:func:`fleet_with_commanders`), then
    ``overrides``, so that ``--set planner.*`` reaches them; None when it is not a fleet."""
    from cufund.scenarios.schema import load_scenario, parse_overrides

    config = load_scenario(scenario)
    if getattr(config, "vehicles", None) is None:
        return None
    return fleet_with_commanders(config).with_overrides(parse_overrides(list(overrides)))


class FleetGcsServer:
    """A live fleet of ``scenario`` and its ground station (see the module docstring). :meth:`start` (inside a
    running asyncio loop) returns the page's URL."""

    def __init__(
        self,
        scenario: Any,
        overrides: tuple[str, ...] = (),
        speed: float = 1.0,
        host: str = "127.0.0.1",
        port: int = 0,
        token: str | None = None,
        port_fallback: bool = False,
        autostart: bool = False,
    ) -> None:
        from ..mavlink.fleet_live import LiveFleet

        self.speed = parse_speed(speed)
        config = _station_config(scenario, overrides) if isinstance(scenario, (str, Path)) else scenario
        if getattr(config, "vehicles", None) is None:
            name = getattr(config, "name", scenario)
            raise ValueError(f"scenario {name!r} is not a fleet (no 'vehicles:'): use the single-vehicle station")
        self.scenario = config.name
        self.live = LiveFleet(fleet_with_commanders(config), speed=self.speed, start=False)
        self.names = self.live.names
        self.colours = {n: FLEET_COLOURS[i % len(FLEET_COLOURS)] for i, n in enumerate(self.names)}
        self.host, self.port = host, int(port)
        self.port_fallback = port_fallback
        self.port_note = ""
        self.token = token or secrets.token_urlsafe(24)
        self.hosts: Any = None
        self._http: Any = None
        self._events: collections.deque[dict[str, Any]] = collections.deque(maxlen=MAX_EVENTS)
        self._event_index = dict.fromkeys(self.names, 0)
        self._lock = threading.Lock()
        self._preview: dict[str, Any] | None = None
        self._preview_mission: Any = None
        self._ids = itertools.count(1)
        self._seq = 0
        self.held = getattr(config, "mission", None) is not None and not autostart
        """A fleet with a mission of its own (``fleet_survey``'s) waits at its first instant for ``start``."""
        self.areas = _areas(self.live.fleet)
        """The scenario's named fields and geofence, drawn on the map: ``{"fields": {name: [[x, y], ...]},
        "geofence": [[x, y], ...] | None}``."""

    # ---- lifecycle -----------------------------------------------------------------------------------------
    def start(self) -> str:
        handlers = [
            (r"/", FleetPageHandler, {"gcs": self}),
            (r"/api/state", FleetStateHandler, {"gcs": self}),
            (r"/api/command", FleetCommandHandler, {"gcs": self}),
            (r"/api/mission/preview", FleetPreviewHandler, {"gcs": self}),
            (r"/api/mission/fly", FleetFlyHandler, {"gcs": self}),
            (r"/static/(fleet\.js)", tornado.web.StaticFileHandler, {"path": str(STATIC_DIR)}),
        ]
        try:
            self._http, self.port, self.hosts = listen(handlers, self.host, self.port)
        except OSError:
            if not self.port_fallback or self.port == 0:
                self.live.stop()
                raise
            wanted = self.port
            self._http, self.port, self.hosts = listen(handlers, self.host, 0)
            self.port_note = f"port {wanted} is in use; serving on port {self.port} instead (choose one with --port)"
        if self.held:  # its first instant (the vehicles on their pads, their first state), then it waits
            self.live.fleet.advance_to(HELD_AT_S)
            self.live._capture()
            self.live.pause()
        self.live.start()
        shown = "127.0.0.1" if self.host in ("", "0.0.0.0", "::") else self.host
        return f"http://{shown}:{self.port}/?token={self.token}"

    def stop(self) -> None:
        if self._http is not None:
            self._http.stop()
        self.live.stop()

    # ---- state -------------------------------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        vehicles = {}
        for name, v in self.live.vehicles.items():
            tel = v.telemetry()
            vehicles[name] = {k: tel.get(k) for k in _FLIGHT_KEYS if k in tel}
            self._collect_events(name, v)
        return {
            "scenario": self.scenario,
            "t": self.live.t,
            "paused": self.live.paused,
            "ended": self.live.ended,
            "names": list(self.names),
            "colours": self.colours,
            "vehicles": jsonable(vehicles),
            "events": list(self._events),
            "preview": self._preview,
            "areas": self.areas,
            "held": self.held,
        }

    def _collect_events(self, name: str, v: Any) -> None:
        with self._lock:
            for e in v.events.since(self._event_index[name]):
                self._event_index[name] = e["index"] + 1
                self._log(name, str(e.get("kind", "")), str(e.get("message", "")), e.get("t"))

    def _log(self, vehicle: str, kind: str, message: str, t: Any = None) -> None:
        self._seq += 1
        self._events.append(
            {
                "seq": self._seq,
                "t": float(t) if isinstance(t, (int, float)) else self.live.t,
                "vehicle": vehicle,
                "kind": kind,
                "message": message,
            }
        )

    # ---- commands ------------------------------------------------------------------------------------------
    def _selected(self, vehicles: Any) -> list[str]:
        if vehicles is None or vehicles == "all":
            return list(self.names)
        if not isinstance(vehicles, list) or not vehicles or not all(isinstance(n, str) for n in vehicles):
            raise ValueError(f'vehicles must be "all" or a non-empty list of names, got {str(vehicles)[:60]}')
        unknown = [n for n in vehicles if n not in self.live.vehicles]
        if unknown:
            raise ValueError(f"unknown vehicle {', '.join(unknown)[:60]}: the fleet has {', '.join(self.names)}")
        return list(dict.fromkeys(vehicles))

    async def execute(self, command: Any, vehicles: Any = "all") -> dict[str, Any]:
        """``command`` to the ``vehicles`` named (or all); each vehicle's ack by name. ValueError/TypeError for a
        malformed one (an unknown vehicle, a command the commander cannot parse)."""
        if not isinstance(command, dict) or not isinstance(command.get("command"), str):
            raise TypeError('a command is an object with a \'command\' name, e.g. {"command": "arm"}')
        name = command["command"]
        if name == "start":  # the held fleet's own mission
            if not self.held:
                why = (
                    "the run has started"
                    if getattr(self.live.config, "mission", None) is not None
                    else ("this fleet has no mission of its own: preview one below and Fly it")
                )
                return {"command": name, "acks": {"fleet": {"result": "denied", "message": why}}}
            self.held = False
            self.live.resume()
            self._log("fleet", "command", "start: accepted")
            return {"command": name, "acks": {"fleet": {"result": "accepted", "message": ""}}}
        if name in ("sim_pause", "sim_resume"):
            if name == "sim_resume":
                self.held = False  # resumed: started
            (self.live.pause if name == "sim_pause" else self.live.resume)()
            self._log("fleet", "command", f"{name}: accepted")
            return {"command": name, "acks": {"fleet": {"result": "accepted", "message": ""}}}
        names = self._selected(vehicles)
        futures = {n: self.live.vehicles[n].submit(command) for n in names}  # ValueError here: malformed
        acks = {n: await _ack(name, f) for n, f in futures.items()}
        for n, a in acks.items():
            self._log(n, "command", f"{name}: {a['result']}" + (f" ({a['message']})" if a["message"] else ""))
        return {"command": name, "acks": acks}

    # ---- missions ------------------------------------------------------------------------------------------
    async def preview(self, text: Any, vehicles: Any = None, area: Any = None) -> dict[str, Any]:
        """The mission ``text`` asks for, as waypoints per vehicle, kept as the one :meth:`fly` may fly; or
        ``{"ok": False, "reason"}``. Read off the server's thread: free text may wait for a chat endpoint (up to
        its timeout), and the station goes on showing the fleet and taking commands meanwhile."""
        from cufund.missions import MissionRequestError

        if not isinstance(text, str) or not text.strip():
            return {"ok": False, "reason": "type a request, e.g. 'zigzag with 3 rows of 5 waypoints at 3 m'"}
        if len(text) > 2000:
            return {"ok": False, "reason": f"the request is {len(text)} characters long; at most 2000"}
        try:
            selection = None if vehicles in (None, "all") else self._selected(vehicles)
            loop = asyncio.get_running_loop()
            mission, waypoints = await loop.run_in_executor(None, self._understand, text, selection, area)
        except (MissionRequestError, ValueError, TypeError) as exc:
            self._log("fleet", "denied", f"mission request refused: {exc}")
            return {"ok": False, "reason": str(exc)}
        ident = next(self._ids)
        preview = {
            "ok": True,
            "id": ident,
            "text": text,
            "summary": _summary(mission, waypoints),
            "mission": jsonable(mission.to_data()),
            "waypoints": {n: [[float(c) for c in p] for p in wp] for n, wp in waypoints.items()},
        }
        self._preview, self._preview_mission = preview, mission
        self._log("fleet", "mission", f"preview {ident}: {preview['summary']}")
        return preview

    def _understand(self, text: str, selection: list[str] | None, area: Any) -> tuple[Any, dict[str, Any]]:
        from cufund.missions import parse_mission

        mission = parse_mission(text, self.live.fleet, area=area, vehicles=selection)
        return mission, mission.waypoints(self.live.fleet)

    async def fly(self, ident: Any) -> dict[str, Any]:
        """Flies the mission last previewed, if ``ident`` is its id: per vehicle, arm when disarmed, then its
        commands in order (stopping at the first refused). ``{"ok", "reason"?, "acks": {name: [ack, ...]}}``."""
        preview, mission = self._preview, self._preview_mission
        if preview is None or mission is None:
            return {"ok": False, "reason": "no mission previewed: type a request and press Preview first", "acks": {}}
        if isinstance(ident, bool) or ident != preview["id"]:
            return {
                "ok": False,
                "reason": f"mission {ident!r} is not the one on the map (preview {preview['id']}): preview it again",
                "acks": {},
            }
        commands = mission.commands(self.live.fleet)
        self._preview = self._preview_mission = None  # flown once; a new preview for the next
        acks: dict[str, list[dict[str, Any]]] = {}
        for name, cmds in commands.items():
            v = self.live.vehicles[name]
            sequence = list(cmds)
            if not v.telemetry().get("armed") and any(c.command == "mission_start" for c in sequence):
                sequence.insert(0, {"command": "arm"})
            acks[name] = []
            for c in sequence:
                a = await _ack(_command_name(c), v.submit(c))
                acks[name].append(a)
                self._log(
                    name, "command", f"{a['command']}: {a['result']}" + (f" ({a['message']})" if a["message"] else "")
                )
                if a["result"] not in ("accepted", "in_progress"):
                    break
        ok = all(a and a[-1]["result"] in ("accepted", "in_progress") for a in acks.values())
        out: dict[str, Any] = {"ok": ok, "acks": acks}
        if not ok:
            out["reason"] = "; ".join(
                f"{n}: {a[-1]['command']} {a[-1]['result']} ({a[-1]['message']})"
                for n, a in acks.items()
                if a and a[-1]["result"] not in ("accepted", "in_progress")
            )
        return out


def _areas(fleet: Any) -> dict[str, Any]:
    """The fleet's named fields and geofence (:class:`cufund.missions.fleet_context.FleetContext`), as plain lists;
    none when the mission context cannot be read (the request is then refused with the reason at preview)."""
    try:
        from cufund.missions.fleet_context import FleetContext

        ctx = FleetContext.of(fleet)
    except Exception:
        return {"fields": {}, "geofence": None}
    fence = None if ctx.geofence is None else [[float(x), float(y)] for x, y in ctx.geofence]
    fields = {n: [[float(x), float(y)] for x, y in poly] for n, poly in ctx.fields.items()}
    return {"fields": fields, "geofence": fence}


def _command_name(c: Any) -> str:
    return str(c.get("command") if isinstance(c, dict) else getattr(c, "command", c))


async def _ack(name: str, future: Any) -> dict[str, Any]:
    try:
        ack = await asyncio.wait_for(asyncio.wrap_future(future), ACK_TIMEOUT_S)
    except TimeoutError:
        return {"command": name, "result": "in_progress", "message": "queued; the commander applies it when it runs"}
    return {"command": name, "result": str(getattr(ack, "result", ack)), "message": str(getattr(ack, "message", ""))}


def _summary(mission: Any, waypoints: dict[str, Any]) -> str:
    counts = ", ".join(f"{n} {len(wp)}" for n, wp in waypoints.items())
    z = [float(p[2]) for wp in waypoints.values() for p in wp]
    alt = f" at {min(z):g}-{max(z):g} m" if z and min(z) != max(z) else (f" at {z[0]:g} m" if z else "")
    return f"{getattr(mission, 'kind', type(mission).__name__.lower())}: waypoints {counts}{alt}"


# ---- handlers ------------------------------------------------------------------------------------------------
class _FleetGuarded(_Guarded):
    gcs: FleetGcsServer  # type: ignore[assignment]

    def body(self) -> dict[str, Any]:
        data = loads_strict(self.request.body or b"null")
        if not isinstance(data, dict):
            raise ValueError("the body must be a JSON object")
        return data

    def refuse(self, exc: BaseException) -> None:
        self.set_status(400)
        self.write({"result": "failed", "message": str(exc)[:300]})


class FleetPageHandler(_FleetGuarded):
    def get(self) -> None:
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.write((STATIC_DIR / "fleet.html").read_bytes())


class FleetStateHandler(_FleetGuarded):
    def get(self) -> None:
        self.write(self.gcs.state())


class FleetCommandHandler(_FleetGuarded):
    async def post(self) -> None:
        try:
            data = self.body()
            self.write(await self.gcs.execute(data.get("command"), data.get("vehicles", "all")))
        except (ValueError, TypeError, OverflowError, RecursionError) as exc:
            self.refuse(exc)


class FleetPreviewHandler(_FleetGuarded):
    async def post(self) -> None:
        try:
            data = self.body()
        except (ValueError, TypeError, RecursionError) as exc:
            self.refuse(exc)
            return
        self.write(await self.gcs.preview(data.get("text"), data.get("vehicles"), data.get("area")))


class FleetFlyHandler(_FleetGuarded):
    async def post(self) -> None:
        try:
            data = self.body()
        except (ValueError, TypeError, RecursionError) as exc:
            self.refuse(exc)
            return
        self.write(await self.gcs.fly(data.get("id")))

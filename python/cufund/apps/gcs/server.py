"""The web ground station's server: one page, a websocket and an HTTP API in front of a live run (tornado).

Routes (every one but the static assets needs the token, as ``?token=`` or ``Authorization: Bearer``; 403
without it, with a ``Host`` that does not name this server, or with another site's ``Origin`` on a POST or the
websocket — see :mod:`cufund.apps.gcs.guard`):

- ``GET /`` the page; ``GET /static/...`` its scripts (``view.js``, the 3-D view, runs in a Web Worker) and style;
  ``GET /meshcat/main.min.js`` MeshCat's bundle, for its three.js, served from the installed ``meshcat`` package
  (MeshCat's own server is never started: it binds every interface).
- ``GET /api/stats`` the server's own figures: CPU time of its event-loop thread (everything but the simulation),
  open tabs, telemetry messages broadcast.
- ``GET /api/state`` the telemetry as JSON; ``POST /api/command`` a JSON command (``{"command": "arm"}``, ...) →
  its acknowledgement ``{"command", "result", "message"}`` (HTTP 400 for a malformed one).
- ``GET /ws`` the page's websocket. Server → page: JSON ``hello`` (the scene and everything needed to catch up),
  ``telemetry`` (at ``telemetry_hz``, and at once when the commander has applied a command), ``events``, ``planned``, ``esdf``, ``gates`` (the gates the vehicle detected, in its estimated frame, when they change), ``ack``, ``error``, ``pong``; binary
  frames are LiDAR clouds (float32 ``[t, n, x, y, z, ...]``, world frame) for tabs with the cloud layer on.
  Page → server: ``{"type": "command", "id": n, "command": {...}}``, ``{"type": "layers", "cloud": bool}``,
  ``{"type": "ping", ...}``, ``{"type": "seen", "telemetry": n, "cloud": m}`` (messages of each stream processed
  on this connection: from then on at most :data:`IN_FLIGHT` are unread, the rest skipped). Anything else gets an
  ``error`` reply; the run goes on.

Bounds: a message or body larger than :data:`cufund.apps.gcs.guard.MAX_MESSAGE_BYTES` is refused (the websocket closed with 1009, the
request with 400); a tab that leaves more than :data:`~cufund.apps.gcs.guard.MAX_UNSENT_BYTES` or
:data:`~cufund.apps.gcs.guard.MAX_UNSENT_MESSAGES` unsent is dropped (one line on stderr; counted in ``/api/stats`` as ``dropped_clients``). Errors are ``error`` replies or 4xx
with a JSON ``message``, never a traceback; no log line carries the token (see :mod:`cufund.apps.gcs.guard`).

The run waits for the operator: a scenario with a commander flies nothing before a command (a scenario's own
mission, such as the tunnel's, waits for ``start``); one without a commander (its planner flies the scenario's
trajectory by itself) is held at t = 0 until ``start``. ``autostart=True`` starts at once (for scripts). A scenario
whose mission a commander can fly (the tunnel's: ``planner: null`` with a ``mission``) gets one
(``planner.kind=commander``), so that arm, take-off, hold, land and return work before and after its mission. Every
tab is told what the scenario supports (``capabilities`` in ``hello``; ``start`` in each telemetry message): the
page disables what it cannot serve and says why.

Commands the ground station handles itself (the rest go to the vehicle's commander): ``start`` (the scenario's
mission, or the held run), ``sim_pause``,
``sim_resume``, ``sim_speed {speed}`` (0.1-10, or "inf"), ``sim_restart {scenario}`` (a new live run, with the
command line's overrides only if it is the command line's scenario; every tab gets its scene; a built-in
scenario name, the command line's scenario or a YAML file inside the run directory, nothing else), ``tunnel_start`` (restart with the ``tunnel`` scenario), ``mission_preview {formula, regions}``.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import math
import os
import secrets
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import tornado.web
import tornado.websocket

from .guard import (
    BoundedSender,
    Hosts,
    authorized,
    listen,
    loads_strict,
    origin_host,
    quiet_errors,
)
from .mission_preview import preview_mission
from .session import GcsSession, jsonable, position_of

__all__ = ["GcsServer", "parse_speed"]

STATIC_DIR = Path(__file__).parent / "static"
ACK_TIMEOUT_S = 3.0
"""How long a command waits for the commander's acknowledgement before the reply says ``in_progress``."""
IN_FLIGHT = {"telemetry": 8, "cloud": 2}
"""Messages of each stream a tab that acknowledges them (``seen``) may have unread: a busy tab gets fresh data late
rather than stale data in order."""
INPUT_ERRORS = (ValueError, TypeError, OverflowError, RecursionError)
"""What a malformed command or message raises (a 4xx or an ``error`` reply, with its message)."""
LOCAL = ("start", "sim_pause", "sim_resume", "sim_speed", "sim_restart", "tunnel_start", "mission_preview")
COMMANDER_COMMANDS = (
    "arm",
    "disarm",
    "takeoff",
    "land",
    "rtl",
    "hold",
    "goto",
    "flight_mode",
    "controller",
    "mission_upload",
    "mission_start",
    "mission_clear",
)
"""What the page's buttons send to the vehicle's commander (disabled, with the reason, without one)."""
HELD_AT_S = 0.01
"""Where a run held for Start waits [s of simulated time]: past its first instant, so that it has telemetry."""
AUTOSTART_TRY_S = 0.5
"""With ``autostart``: how often ``start`` is tried until the vehicle accepts it (its estimator initialising) [s]."""
AUTOSTART_GIVE_UP_S = 120.0
"""With ``autostart``: how long [s, wall clock] it is tried before the refusal is reported and it stops trying."""


def parse_speed(value: Any) -> float:
    """A simulation speed: a number in [0.1, 10] times real time, or ``inf``/``max`` (as fast as possible)."""
    if isinstance(value, str) and value.strip().lower() in ("inf", "max", "fast"):
        return math.inf
    try:
        speed = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"speed must be a number in [0.1, 10] or 'inf', got {_short(value)}") from None
    if not (math.isinf(speed) and speed > 0) and not 0.1 <= speed <= 10.0:
        raise ValueError(f"speed must be a number in [0.1, 10] or 'inf', got {_short(value)}")
    return speed


def _short(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a 4000-digit number is not echoed whole)."""
    try:
        text = repr(value)
    except ValueError:  # an int too long for str()
        return f"<{type(value).__name__} too long to show>"
    return text if len(text) <= limit else text[:limit] + "..."


def _meshcat_dist() -> Path:
    from cufund.viz.meshcat_scene import import_meshcat

    return Path(import_meshcat().__file__).parent / "viewer" / "dist"


def with_commander(config: Any) -> Any:
    """``config`` with a commander when its mission can be flown by one and it has no planner (the tunnel's):
    ``planner.kind=commander``; otherwise ``config`` as it is."""
    mission = getattr(config, "mission", None)
    if getattr(config, "planner", None) is None and mission is not None and mission.kind == "tunnel":
        return config.with_overrides({"planner.kind": "commander"})
    return config


def _default_live(scenario: str, overrides: tuple[str, ...], speed: float) -> Any:
    from cufund.scenarios.schema import load_scenario, parse_overrides

    from ..live import LiveRun

    # not started: the server holds it first when it must wait for Start (GcsServer._open starts it)
    return LiveRun(with_commander(load_scenario(scenario, parse_overrides(list(overrides)))), (), speed, start=False)


def capabilities(live: Any) -> dict[str, Any]:
    """What the scenario of ``live`` supports, for the page: ``commander`` (bool), ``mission`` (the scenario has
    a mission of its own that ``start`` flies), ``controllers`` (the kinds built in) and ``disabled`` (command name
    -> why it cannot be served)."""
    commander = getattr(live, "commander", None)
    config = getattr(live, "config", None)
    disabled: dict[str, str] = {}
    if commander is None:
        planner = getattr(getattr(config, "planner", None), "kind", None)
        why = (
            f"no commander in this scenario: its planner ({planner}) flies the scenario's trajectory by itself"
            if planner
            else "no commander in this scenario: it flies the scenario's trajectory by itself"
        )
        disabled = dict.fromkeys(COMMANDER_COMMANDS, why)
        controllers: list[str] = []
    else:
        controllers = list(getattr(commander, "controllers", ()))
        if len(controllers) < 2:
            disabled["controller"] = f"only {', '.join(controllers) or 'one controller'} is built into this simulation"
    mission = getattr(commander, "scenario_mission", None) if commander is not None else None
    return {
        "commander": commander is not None,
        "mission": mission is not None,
        "controllers": controllers,
        "disabled": disabled,
    }


class GcsServer:
    """A live run of ``scenario`` and the ground station serving it (see the module docstring).

    Call :meth:`start` inside a running asyncio loop; it returns the page's URL. ``live_factory(scenario,
    overrides, speed)`` makes the live run (default :class:`cufund.apps.live.LiveRun`). ``run_dir`` (default: the
    current directory) is where ``sim_restart`` may load scenario files from. ``foxglove``, a
    :class:`~cufund.apps.gcs.foxglove_bridge.FoxgloveBridge`, is started with this server's token.
    """

    def __init__(
        self,
        scenario: str,
        overrides: tuple[str, ...] = (),
        speed: float = 1.0,
        host: str = "127.0.0.1",
        port: int = 0,
        token: str | None = None,
        telemetry_hz: float = 50.0,
        live_factory: Callable[[str, tuple[str, ...], float], Any] = _default_live,
        foxglove: Any = None,
        run_dir: str | os.PathLike[str] | None = None,
        autostart: bool = False,
        port_fallback: bool = False,
    ) -> None:
        if not (isinstance(telemetry_hz, (int, float)) and 1.0 <= telemetry_hz <= 200.0):
            raise ValueError(f"telemetry_hz must be a number in [1, 200], got {telemetry_hz!r}")
        self.scenario = self.first_scenario = scenario
        self.overrides = tuple(overrides)
        self.speed = parse_speed(speed)
        self.host = host
        self.port = int(port)
        self.token = token or secrets.token_urlsafe(24)
        self.telemetry_hz = float(telemetry_hz)
        self.live_factory = live_factory
        self.foxglove = foxglove
        self.session: GcsSession | None = None
        self.clients: set[SocketHandler] = set()
        self.seq = 0
        self._http: tornado.httpserver.HTTPServer | None = None
        self._ticker: tornado.ioloop.PeriodicCallback | None = None
        self._esdf_sent: Any = None
        self._restarting = False
        self._paused = False
        self._last_error = ""
        self.run_dir = Path(run_dir if run_dir is not None else os.getcwd()).resolve()
        self.hosts: Hosts | None = None
        self.dropped_clients = 0
        """Tabs dropped because they did not read what was sent to them."""
        self.autostart = bool(autostart)
        self.port_fallback = bool(port_fallback)
        """When ``port`` is taken, serve on a free one (and say so in :attr:`port_note`) instead of failing."""
        self.port_note = ""
        self.held = False
        """A run without a commander held at t = 0 until ``start``."""
        self.started = False
        """``start`` was accepted for the current run."""
        self._autostart_due: float | None = None
        self._autostart_until = 0.0
        self._autostart_future: Any = None

    # ---- lifecycle -----------------------------------------------------------------------------------------
    def start(self) -> str:
        """Builds the live run, binds the port and starts broadcasting; returns the page's URL (with token)."""
        self._open(self.live_factory(self.scenario, self.overrides, self.speed), self.scenario)
        handlers = [
            (r"/", PageHandler, {"gcs": self}),
            (r"/api/state", StateHandler, {"gcs": self}),
            (r"/api/stats", StatsHandler, {"gcs": self}),
            (r"/api/command", CommandHandler, {"gcs": self}),
            (r"/ws", SocketHandler, {"gcs": self}),
            (r"/static/(.*)", tornado.web.StaticFileHandler, {"path": str(STATIC_DIR)}),
            (r"/meshcat/(main\.min\.js)", tornado.web.StaticFileHandler, {"path": str(_meshcat_dist())}),
        ]
        try:
            self._http, self.port, self.hosts = self._listen(handlers)
        except Exception:
            self.stop()
            raise
        if self.foxglove is not None and hasattr(self.foxglove, "start"):
            self.foxglove.start(self.token)
        self._ticker = tornado.ioloop.PeriodicCallback(self._tick, 1000.0 / self.telemetry_hz)
        self._ticker.start()
        shown = "127.0.0.1" if self.host in ("", "0.0.0.0", "::") else self.host
        return f"http://{shown}:{self.port}/?token={self.token}"

    def _listen(self, handlers: list[Any]) -> Any:
        """Binds :attr:`port`; when it is taken and :attr:`port_fallback`, a free port, noted in :attr:`port_note`."""
        try:
            return listen(handlers, self.host, self.port)
        except OSError as exc:
            if not self.port_fallback or self.port == 0 or exc.errno != errno.EADDRINUSE:
                raise OSError(exc.errno, f"cannot serve on {self.host}:{self.port}: {exc.strerror}") from exc
            wanted = self.port
            found = listen(handlers, self.host, 0)
            self.port_note = f"port {wanted} is in use; serving on port {found[1]} instead (choose one with --port)"
            return found

    def _open(self, live: Any, scenario: str) -> None:
        self.session = GcsSession(live, scenario)
        self.session.capabilities = capabilities(live)
        add = getattr(live, "add_listener", None)
        if add is not None:
            add(self.session.sample_esdf, 1.0)
        self._esdf_sent = None
        self._paused = False
        self.started = False
        self.held = getattr(live, "commander", None) is None and not self.autostart
        if self.held:  # no commander: nothing would wait for the operator, so the run waits at t = 0
            sim = getattr(live, "simulator", None)
            if sim is not None and not getattr(live, "running", True):
                sim.advance_to(HELD_AT_S)  # its first instant: the vehicle on its pad, its sensors' first messages
            live.pause()
        start = getattr(live, "start", None)
        if callable(start):  # a live run made not started (the default factory's), held or not
            start()
        self._autostart_future = None
        self._autostart_due = None
        if self.autostart and self.session.capabilities["mission"]:  # tried until the vehicle accepts it
            self._autostart_due, self._autostart_until = 0.0, time.monotonic() + AUTOSTART_GIVE_UP_S
        elif self.autostart:
            self.started = True

    def start_state(self) -> dict[str, Any]:
        """Whether ``start`` can be served now: ``{"available": bool, "why": str, "started": bool}``."""
        session = self.session
        if session is None:
            return {"available": False, "why": "no run", "started": False}
        live = session.live
        commander = getattr(live, "commander", None)
        if commander is None:
            ok = self.held
            return {"available": ok, "why": "" if ok else "the run has started", "started": not ok}
        mission = getattr(commander, "scenario_mission", None)
        if mission is None:
            return {
                "available": False,
                "why": "this scenario has no mission of its own: upload waypoints below and press their Start",
                "started": self.started,
            }
        if getattr(mission, "t_go", None) is not None or mission.finished:
            why = (
                f"the mission has run ({mission.state}); restart the scenario to fly it again"
                if mission.finished
                else f"the mission is running ({mission.state})"
            )
            return {"available": False, "why": why, "started": True}
        if not commander.landed:
            return {"available": False, "why": "the mission takes off from the ground: land first", "started": False}
        return {"available": True, "why": "", "started": False}

    def stop(self) -> None:
        """Stops broadcasting, closes every websocket and the port, and stops the live run."""
        if self._ticker is not None:
            self._ticker.stop()
        for c in list(self.clients):
            c.close()
        if self._http is not None:
            self._http.stop()
        if self.session is not None:
            self.session.live.stop()

    # ---- broadcasting --------------------------------------------------------------------------------------
    def _tick(self) -> None:
        session = self.session
        if session is None or self._restarting:
            return
        try:
            tel = session.poll()
            events = session.new_events()
            gates = session.new_gates()  # the detector's gates, kept for tabs that connect later too
        except Exception as exc:  # a failing run must not stop the server; show why (once)
            message = f"telemetry: {type(exc).__name__}: {exc}"
            if message != self._last_error:
                self._last_error = message
                self.broadcast({"type": "error", "message": message})
            return
        self._last_error = ""
        if self._autostart_due is not None:
            self._autostart(session)
        if not self.clients and self.foxglove is None:
            return  # the path and history above still grow for the next tab
        self.seq += 1
        text = json.dumps(
            {
                "type": "telemetry",
                "seq": self.seq,
                "wall": time.time(),
                "paused": self._paused or self.held,
                "speed": None if math.isinf(self.speed) else self.speed,
                "start": self.start_state(),
                **tel,
            }
        )
        for c in list(self.clients):
            c.send(text, stream="telemetry")
        if events:
            self.broadcast({"type": "events", "events": events})
        if session.planned_changed:
            session.planned_changed = False
            self.broadcast({"type": "planned", "planned": session.planned, "planned_label": session.planned_label})
        if gates is not None:
            self.broadcast(gates)
        if any(c.cloud for c in self.clients) or self.foxglove is not None:
            cloud = session.new_cloud()
            if cloud is not None:
                for c in list(self.clients):
                    if c.cloud:
                        c.send(cloud, stream="cloud")
                if self.foxglove is not None:
                    self.foxglove.cloud(cloud)
        if session.esdf is not None and session.esdf is not self._esdf_sent:
            self._esdf_sent = session.esdf
            self.broadcast(session.esdf)
        if self.foxglove is not None:
            self.foxglove.telemetry(tel, events)

    def _autostart(self, session: GcsSession) -> None:
        """``autostart``: submits the scenario mission's start every :data:`AUTOSTART_TRY_S` until it is accepted
        (the estimator must have initialised first) or :data:`AUTOSTART_GIVE_UP_S` passed (then says why)."""
        fut, now = self._autostart_future, time.monotonic()
        if fut is not None:
            if not fut.done():
                return
            ack = fut.result()
            self._autostart_future = None
            if getattr(ack, "result", "") == "accepted":
                self._autostart_due = None
                self.started = True
                session.log(
                    {"t": session.telemetry.get("t"), "kind": "command", "message": "start: accepted (autostart)"}
                )
                return
            if now > self._autostart_until:
                self._autostart_due = None
                print(f"cufund gcs: autostart gave up: {getattr(ack, 'message', ack)}", file=sys.stderr, flush=True)
                return
        if self._autostart_due is not None and now >= self._autostart_due:
            self._autostart_due = now + AUTOSTART_TRY_S
            self._autostart_future = session.live.submit({"command": "mission_start"})

    def broadcast(self, message: dict[str, Any]) -> None:
        text = json.dumps(message)
        for c in list(self.clients):
            c.send(text)

    # ---- commands ------------------------------------------------------------------------------------------
    async def execute(self, command: Any) -> dict[str, Any]:
        """Runs one command; returns its acknowledgement. A malformed command raises ``ValueError`` or
        ``TypeError``."""
        if not isinstance(command, dict) or not isinstance(command.get("command"), str):
            raise TypeError(f"a command is an object with a 'command' name, got {_short(command)}")
        name = command["command"]
        session = self.session
        if session is None or self._restarting:
            return {"command": name, "result": "denied", "message": "the simulation is restarting"}
        if name in LOCAL:
            ack = await self._local(name, command)
        else:
            ack = await self._vehicle(name, command)
        self.broadcast(
            {
                "type": "events",
                "events": [
                    session.log(
                        {
                            "t": session.telemetry.get("t"),
                            "kind": "command",
                            "message": f"{name}: {ack['result']}"
                            + (f" ({ack['message']})" if ack.get("message") else ""),
                        }
                    )
                ],
            }
        )
        return ack

    async def _vehicle(self, name: str, command: dict[str, Any]) -> dict[str, Any]:
        session = self.session
        assert session is not None
        future = session.live.submit(command)  # a malformed command raises ValueError here or in the future
        # the commander's new state (a go-to's target) goes to every tab as soon as it is applied: scheduled on the
        # event loop straight from the simulation thread, not with the next tick nor after the ack's way back here
        loop = asyncio.get_running_loop()

        def push(_: Any) -> None:
            with contextlib.suppress(RuntimeError):  # the loop has closed: the server stopped meanwhile
                loop.call_soon_threadsafe(self._tick)

        future.add_done_callback(push)
        try:
            ack = await asyncio.wait_for(asyncio.wrap_future(future), ACK_TIMEOUT_S)
        except TimeoutError:
            return {
                "command": name,
                "result": "in_progress",
                "message": "queued; the commander applies it when the simulation runs",
            }
        reply = {
            "command": name,
            "result": str(getattr(ack, "result", ack)),
            "message": str(getattr(ack, "message", "")),
        }
        extra = getattr(ack, "data", None)
        if extra is not None:
            reply["data"] = jsonable(extra)
        return reply

    async def _local(self, name: str, command: dict[str, Any]) -> dict[str, Any]:
        session = self.session
        assert session is not None
        live = session.live
        if name == "start":
            return await self._start(command)
        if name == "sim_pause":
            live.pause()
            self._paused = True
        elif name == "sim_resume":
            if self.held:
                return {"command": name, "result": "denied", "message": "the run waits for Start"}
            live.resume()
            self._paused = False
        elif name == "sim_speed":
            self.speed = parse_speed(command.get("speed"))
            live.set_speed(self.speed)
        elif name == "mission_preview":
            p = position_of(session.telemetry)
            plan = preview_mission(command, session.regions(), p if p is not None else np.zeros(3))
            start = [] if p is None else [p.tolist()]
            self.broadcast(session.set_planned(start + plan["waypoints_W"], "LTLf: " + " → ".join(plan["regions"])))
            return {
                "command": name,
                "result": "accepted",
                "message": f"{len(plan['regions'])} regions, {plan['length']:.2f} m",
                "data": plan,
            }
        else:
            scenario = "tunnel" if name == "tunnel_start" else command.get("scenario", session.scenario)
            if not isinstance(scenario, str) or not scenario:
                raise TypeError(f"sim_restart needs 'scenario', a scenario name or path, got {_short(scenario)}")
            await self._restart(scenario, self._scenario_source(scenario))
            return {"command": name, "result": "accepted", "message": f"running {scenario}"}
        return {"command": name, "result": "accepted", "message": ""}

    async def _start(self, command: dict[str, Any]) -> dict[str, Any]:
        """``start``: the scenario's own mission (the commander's ``mission_start``), or a held run goes on."""
        state = self.start_state()
        session = self.session
        assert session is not None
        if self.held:
            self.held = False
            self.started = True
            if not self._paused:
                session.live.resume()
            return {"command": "start", "result": "accepted", "message": "the run goes on"}
        if not state["available"]:
            return {"command": "start", "result": "denied", "message": state["why"]}
        ack = await self._vehicle("start", {**command, "command": "mission_start"})
        if ack["result"] == "accepted":
            self.started = True
        return ack

    def _scenario_source(self, scenario: str) -> str:
        """What the live run is built from for ``sim_restart {scenario}``: a built-in name or the command line's
        scenario as given, a YAML file inside :attr:`run_dir` as its resolved path; anything else is refused
        (``ValueError``) without reading it."""
        from cufund.scenarios.schema import available_scenarios

        builtin = available_scenarios()
        if scenario == self.first_scenario or scenario in builtin:
            return scenario
        refused = ValueError(
            f"sim_restart takes a built-in scenario ({', '.join(builtin)}) or a .yaml file in the "
            f"run directory {self.run_dir}; got {_short(scenario, 200)}"
        )
        try:
            path = (self.run_dir / scenario).resolve()
        except (OSError, RuntimeError, ValueError):
            raise refused from None
        if path.suffix not in (".yaml", ".yml") or not path.is_relative_to(self.run_dir) or not path.is_file():
            raise refused
        return str(path)

    async def _restart(self, scenario: str, source: str | None = None) -> None:
        """Replaces the live run by a new one of ``scenario`` (built off the event loop from ``source``, default
        ``scenario``); every tab gets the new scene. The old run goes on if the new one cannot be built: the reply
        names why for a built-in scenario, only the kind of error for a file (its reason, which may quote the file,
        goes to the server's stderr)."""
        old = self.session
        assert old is not None
        source = scenario if source is None else source
        self._restarting = True
        loop = asyncio.get_running_loop()
        try:
            # the command line's --set overrides belong to its scenario, not to another one
            overrides = self.overrides if scenario == self.first_scenario else ()
            live = await loop.run_in_executor(None, self.live_factory, source, overrides, self.speed)
        except Exception as exc:
            self._restarting = False
            if source == scenario and not Path(scenario).suffix:  # a built-in name: its own text may be shown
                raise ValueError(f"cannot start scenario {scenario!r}: {exc}") from exc
            print(
                f"cufund gcs: cannot start scenario {source}: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True
            )
            raise ValueError(
                f"cannot start scenario {_short(scenario, 200)}: {type(exc).__name__} (the reason is on "
                "the ground station's console)"
            ) from exc
        await loop.run_in_executor(None, old.live.stop)
        self._open(live, scenario)
        self.scenario = scenario
        self._restarting = False
        for c in list(self.clients):
            c.send(json.dumps(self.session.catch_up()))  # type: ignore[union-attr]


def _same_origin(handler: tornado.web.RequestHandler, origin: str | None) -> bool:
    """An ``Origin`` (when the client sent one) that is this server as the request's ``Host`` names it."""
    return origin is None or origin_host(origin) == handler.request.host.lower()


def _refusal(handler: tornado.web.RequestHandler, gcs: GcsServer) -> str:
    """Why a request is refused ("" when it is not): no token, a ``Host`` that is not this server, another
    site's ``Origin`` on anything but a GET."""
    if gcs.hosts is not None and handler.request.host not in gcs.hosts:
        return "Host does not name this server"
    if not authorized(handler, gcs.token):
        return "token required (?token= or Authorization: Bearer)"
    if handler.request.method != "GET" and not _same_origin(handler, handler.request.headers.get("Origin")):
        return "cross-origin request refused"
    return ""


class _Guarded(quiet_errors, tornado.web.RequestHandler):
    def initialize(self, gcs: GcsServer) -> None:
        self.gcs = gcs

    def prepare(self) -> None:
        why = _refusal(self, self.gcs)
        if why:
            raise tornado.web.HTTPError(403, reason=why)

    def set_default_headers(self) -> None:
        self.set_header("Cache-Control", "no-store")


class PageHandler(_Guarded):
    def get(self) -> None:
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.write((STATIC_DIR / "index.html").read_bytes())


class StateHandler(_Guarded):
    def get(self) -> None:
        session = self.gcs.session
        self.write(jsonable(session.live.telemetry()) if session is not None else {})


class CommandHandler(_Guarded):
    async def post(self) -> None:
        try:
            command = loads_strict(self.request.body or b"null")
            ack = await self.gcs.execute(command)
        except INPUT_ERRORS as exc:  # JSON decoding errors and the commander's parsing too
            self.set_status(400)
            self.write({"result": "failed", "message": _message(exc)})
            return
        self.write(ack)


class StatsHandler(_Guarded):
    def get(self) -> None:
        self.write(
            {
                "io_thread_cpu_s": time.thread_time(),
                "tabs": len(self.gcs.clients),
                "telemetry_sent": self.gcs.seq,
                "dropped_clients": self.gcs.dropped_clients,
            }
        )


def _message(exc: BaseException) -> str:
    """An exception as the reply's message: its text, or its kind when it has none."""
    if isinstance(exc, RecursionError):
        return "the message is nested too deeply"
    return str(exc) or type(exc).__name__


class SocketHandler(quiet_errors, BoundedSender, tornado.websocket.WebSocketHandler):
    def initialize(self, gcs: GcsServer) -> None:
        self.gcs = gcs
        self.cloud = False
        self._pending: dict[str, Any] = {}
        self.sent = dict.fromkeys(IN_FLIGHT, 0)
        self.seen: dict[str, int] | None = None
        """What the tab has processed of each stream (None until it says: then flow control applies)."""
        self._tasks: set[asyncio.Task[Any]] = set()

    async def get(self, *args: Any, **kwargs: Any) -> None:
        why = _refusal(self, self.gcs)
        if why:
            self.set_status(403)
            self.finish(why)
            return
        await super().get(*args, **kwargs)

    def check_origin(self, origin: str) -> bool:
        return _same_origin(self, origin)

    def open(self, *args: Any, **kwargs: Any) -> None:
        self.set_nodelay(True)
        self.gcs.clients.add(self)
        session = self.gcs.session
        if session is not None:
            self.send(json.dumps(session.catch_up()))

    def on_close(self) -> None:
        if self in self.gcs.clients:  # once per tab (a failed write calls this too)
            self.gcs.clients.discard(self)
            code = self.close_code if self.close_code is not None else "no close frame"
            print(
                f"cufund gcs: a tab closed its connection ({code}); {len(self.gcs.clients)} open",
                file=sys.stderr,
                flush=True,
            )

    def send(self, message: str | bytes, stream: str = "") -> None:
        """Writes ``message``. On a named ``stream`` (telemetry, clouds) a message is skipped while the previous one
        of that stream has not left yet: a slow or dead tab must not queue unbounded data. Any message that would
        leave more than :data:`MAX_UNSENT_BYTES` or :data:`MAX_UNSENT_MESSAGES` unsent drops the tab."""
        pending = self._pending.get(stream)
        if stream and pending is not None and not pending.done():
            return
        if stream and self.seen is not None and self.sent[stream] - self.seen[stream] >= IN_FLIGHT[stream]:
            return
        future = self.send_bounded(message)
        if future is not None and stream:
            self._pending[stream] = future
            self.sent[stream] += 1

    def count_drop(self) -> tuple[str, int]:
        self.gcs.dropped_clients += 1
        return "ground station tab", self.gcs.dropped_clients

    def on_message(self, message: str | bytes) -> None:
        if self.dropped:
            return
        try:
            if isinstance(message, bytes):
                raise TypeError("messages must be JSON text, got a binary frame")
            data = loads_strict(message)
            if not isinstance(data, dict) or not isinstance(data.get("type"), str):
                raise TypeError("a message is a JSON object with a 'type' (command, layers, seen or ping)")
            kind = data["type"]
            if kind == "command":
                task = asyncio.ensure_future(self._command(data.get("id"), data.get("command")))
                self._tasks.add(task)
                task.add_done_callback(self._tasks.discard)
            elif kind == "layers":
                self.cloud = bool(data.get("cloud", self.cloud))
            elif kind == "seen":
                self.seen = {s: _count(data.get(s, 0), s) for s in IN_FLIGHT}
            elif kind == "ping":
                self.send(json.dumps({**data, "type": "pong", "wall": time.time()}))
            else:
                raise ValueError(f"unknown message type {_short(kind)}; expected command, layers, seen or ping")
        except Exception as exc:  # every malformed message gets its error reply; the socket stays open
            self.send(
                json.dumps(
                    {
                        "type": "error",
                        "message": _message(exc) if isinstance(exc, INPUT_ERRORS) else f"{type(exc).__name__}: {exc}",
                    }
                )
            )

    async def _command(self, ident: Any, command: Any) -> None:
        try:
            ack = await self.gcs.execute(command)
        except INPUT_ERRORS as exc:
            ack = {
                "command": command.get("command") if isinstance(command, dict) else None,
                "result": "failed",
                "message": _message(exc),
            }
        except Exception as exc:  # the page gets the reason; the server stays up
            print(f"cufund gcs: {type(exc).__name__}: {exc}", file=sys.stderr)
            ack = {"command": None, "result": "failed", "message": f"{type(exc).__name__}: {exc}"}
        self.send(json.dumps({"type": "ack", "id": ident, **ack}))


def _count(value: Any, name: str) -> int:
    """A ``seen`` count: a whole number of messages >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 2**53 or value != int(value):
        raise ValueError(f"seen.{name} must be a whole number of messages >= 0, got {_short(value)}")
    return int(value)

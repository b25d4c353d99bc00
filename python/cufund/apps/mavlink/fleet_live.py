"""A fleet flown live: every vehicle of a fleet scenario in one world, advanced together in one background thread
paced to the wall clock, each vehicle commanded and watched as a single live run is
(:class:`cufund.apps.live.LiveRun`): ``fleet_live.vehicles[name]`` has the same ``submit``, ``telemetry``,
``events``, ``commander``, ``config`` and ``built`` a :class:`VehicleEndpoint` or the ground station use.

    with LiveFleet("fleet_square") as fleet:
        fleet.vehicles["uav2"].submit({"command": "arm"}).result(timeout=2)
        fleet.submit_all({"command": "takeoff", "altitude": 1.5})

The fleet itself comes from :func:`cufund.scenarios.fleet.build_fleet` (``fleet.names``, ``fleet.advance_to(t)``,
``fleet.t``, ``fleet.vehicle(name)`` with that vehicle's ``simulator``, ``bus`` and ``commander``), or is given
(``fleet=``: anything with that interface). After each advance the thread takes each vehicle's newest messages of
the topics its telemetry reads, so that a reader in another thread sees one instant of each vehicle.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from concurrent.futures import Future
from typing import Any

from cufund.core.messages import Topics
from cufund.missions.commander import Commander
from cufund.missions.controller_params import controller_param_provider
from cufund.missions.events import EventLog

from ..live import RECORD_HZ, LiveRun, _end_kind
from ..paced_loop import PacedLoop

__all__ = ["FleetVehicleRun", "LiveFleet"]

_TELEMETRY_TOPICS = (
    Topics.TRUTH_ODOMETRY,
    Topics.ESTIMATE,
    Topics.TRAJECTORY_SETPOINT,
    Topics.THRUST_TORQUE_SETPOINT,
    Topics.BATTERY,
)
"""What :meth:`LiveRun.telemetry` reads of a vehicle's bus."""
_KEEP_LINK_INSTANTS = 300_000
"""Instants a formation link of a live fleet keeps of its truth samples (20 minutes at the fleet's 250 Hz)."""


class _Snapshot:
    """LiveRun's tap, filled by the fleet's thread: (time, newest message by topic), swapped whole."""

    def __init__(self) -> None:
        self.snapshot: tuple[float | None, dict[str, Any]] = (None, {})

    @property
    def latest(self) -> dict[str, Any]:
        return self.snapshot[1]


class FleetVehicleRun(LiveRun):
    """One vehicle of a :class:`LiveFleet`, with a single live run's interface (``submit``, ``telemetry``,
    ``latest``, ``events``, ``commander``, ``config``, ``built``, ``add_listener``, ``wait_until``). Pausing, speed
    and stopping are the fleet's: they act on every vehicle."""

    def __init__(self, fleet: LiveFleet, name: str, vehicle: Any, config: Any) -> None:  # no LiveRun.__init__
        self.fleet, self.name, self.member = fleet, name, vehicle
        self.built = getattr(vehicle, "built", vehicle)  # its single-vehicle Built (the fleet's FleetVehicle.built)
        self.simulator = sim = getattr(vehicle, "simulator", vehicle)
        self.config = getattr(vehicle, "config", None) or config
        found = [c for c in getattr(sim, "components", ()) if isinstance(c, Commander)]
        self.commander = getattr(vehicle, "commander", None) or (found[0] if found else None)
        self.events: EventLog = (
            self.commander.events
            if self.commander is not None
            else next(
                (e for c in getattr(sim, "components", ()) if isinstance(e := getattr(c, "events", None), EventLog)),
                EventLog(),
            )
        )  # as LiveRun: without a commander, the failsafe supervisor's
        if self.commander is not None:  # as LiveRun: the controllers' gains by PX4 name (get_params / set_param)
            self.commander.param_providers.append(controller_param_provider(getattr(sim, "components", ())))
        self._tap = _Snapshot()  # type: ignore[assignment]
        self._own_end: str | None = None
        self._errors: dict[str, int] = {}
        for c in getattr(sim, "components", ()):
            self._guard(c)
        self._listeners: list[list[Any]] = []
        self._listeners_lock = threading.Lock()
        self._rate_window = fleet._rate_window
        self._wake = fleet._wake
        self._estimated = getattr(self.config, "estimator", None) is not None
        vp = _vehicle_params(vehicle)
        self._max_thrust = 4.0 * vp.k_f * vp.rotor_speed_max**2
        # a live fleet may last hours: as LiveRun, no message history and the true state at RECORD_HZ only
        if hasattr(sim, "record_topics"):
            sim.record_topics = ()
            ratio = sim.physics_rate_hz / RECORD_HZ
            if ratio == int(ratio) and ratio >= 1:
                sim.record_period = int(ratio)

    # the fleet's state, read where LiveRun keeps its own
    @property
    def ended(self) -> str | None:
        """Why this vehicle's run ended: the fleet's, or its own (a crash) while the others fly on."""
        return self.fleet.ended or self._own_end

    @ended.setter
    def ended(self, value: str | None) -> None:  # LiveRun.__init__ is not run; nothing sets it per vehicle
        pass

    def _finish(self) -> None:
        """Its own run has ended (its simulator's status is set: a crash): as a single live run's end, an event
        and its commander's queued commands failed, so that its clients hear why."""
        sim = self.simulator
        status = getattr(sim.status, "value", str(sim.status))
        self._own_end = f"{status}: {sim.message}"
        self.events.append(float(sim.t), _end_kind(status), self._own_end)
        if self.commander is not None:
            self.commander.cancel_pending(f"the run has ended ({self._own_end})")
        self._notify(force=True)

    @property
    def _speed(self) -> float:  # type: ignore[override]
        return self.fleet.speed

    @property
    def _paused(self) -> bool:  # type: ignore[override]
        return self.fleet.paused

    @property
    def running(self) -> bool:
        return self.fleet.running

    def start(self) -> FleetVehicleRun:
        self.fleet.start()
        return self

    def stop(self, timeout: float = 10.0) -> None:
        self.fleet.stop(timeout)

    def pause(self) -> None:
        self.fleet.pause()

    def resume(self) -> None:
        self.fleet.resume()

    def set_speed(self, x: float) -> None:
        self.fleet.set_speed(x)

    def _capture(self, t: float) -> None:
        bus = getattr(self.member, "bus", None) or getattr(self.simulator, "bus", None)
        if bus is None:
            return
        snap = {}
        for topic in _TELEMETRY_TOPICS:
            m = bus.latest(str(topic))
            if m is not None:
                snap[str(topic)] = m
        self._tap.snapshot = (t, snap)


def _vehicle_params(vehicle: Any) -> Any:
    ctx = getattr(vehicle, "context", None)
    if ctx is not None and getattr(ctx, "vehicle", None) is not None:
        return ctx.vehicle
    sim = getattr(vehicle, "simulator", vehicle)
    return sim.vehicle.params


class LiveFleet(PacedLoop):
    """Builds the fleet scenario ``scenario_or_config`` (as :class:`LiveRun` takes it; or flies ``fleet`` given
    built) and runs it at ``speed`` x real time (``math.inf``: as fast as it goes), every vehicle advanced to the
    same time before any goes further. ``vehicles`` maps each name to its :class:`FleetVehicleRun`, in fleet
    order. Starts at once unless ``start=False``. As with a live run, the commanders' scripted commands are dropped
    unless ``script=True``: a live vehicle waits for its operator."""

    def __init__(
        self,
        scenario_or_config: Any = None,
        overrides: Iterable[str] | dict[str, Any] = (),
        speed: float = 1.0,
        start: bool = True,
        fleet: Any = None,
        script: bool = False,
    ) -> None:
        self._init_pacing(speed)
        config = None
        if fleet is None:
            if scenario_or_config is None:
                raise ValueError("LiveFleet needs a fleet scenario (name, path, dict or ScenarioConfig) or fleet=")
            config = LiveRun._config(scenario_or_config, overrides)
            if getattr(config, "vehicles", None) is None:
                raise ValueError(
                    f"scenario {config.name!r} has one vehicle (no 'vehicles:' list); serve it as a single vehicle"
                )
            if not script:
                config = _without_scripts(config)
            from cufund.scenarios.fleet import build_fleet  # type: ignore[import-not-found, unused-ignore]

            # a live vehicle's run never ends where `cufund run`'s would (landed after its reference, or the
            # scenario's mission through): as a single LiveRun's, it goes on for its operator until stopped
            fleet = build_fleet(config, until_done=False)
        self.fleet = fleet
        for link in getattr(fleet, "formation_links", {}).values():  # as the vehicles' records, the last ~20 min
            link.keep_rows = _KEEP_LINK_INSTANTS
        self.config = config if config is not None else getattr(fleet, "config", None)
        self.names: tuple[str, ...] = tuple(fleet.names)
        self.vehicles: dict[str, FleetVehicleRun] = {
            n: FleetVehicleRun(self, n, fleet.vehicle(n), self.config) for n in self.names
        }
        self._capture()
        if start:
            self.start()

    # -- control (start, pause, resume, set_speed, stop: PacedLoop's) --------------------------------------------
    _thread_name = "cufund-live-fleet"

    @property
    def t(self) -> float:
        return float(self.fleet.t)

    def vehicle(self, name: str) -> FleetVehicleRun:
        try:
            return self.vehicles[name]
        except KeyError:
            raise KeyError(f"no vehicle {name!r} in this fleet; it has {list(self.names)}") from None

    def submit_all(self, cmd: Any) -> dict[str, Future]:
        """``cmd`` to every vehicle (each checks it as its own :meth:`LiveRun.submit` does): a Future per name."""
        return {n: v.submit(cmd) for n, v in self.vehicles.items()}

    def telemetry(self) -> dict[str, dict[str, Any]]:
        """Every vehicle's :meth:`LiveRun.telemetry`, by name."""
        return {n: v.telemetry() for n, v in self.vehicles.items()}

    # -- the simulation thread -----------------------------------------------------------------------------------
    def _capture(self) -> None:
        t = float(self.fleet.t)
        for v in self.vehicles.values():
            v._capture(t)

    # PacedLoop's loop, with these hooks
    def _sim_t(self) -> float:
        return float(self.fleet.t)

    def _advance_to(self, t: float) -> bool:
        return self.fleet.advance_to(t) is not False

    def _after_advance(self) -> None:
        self._capture()
        for v in self.vehicles.values():
            if v._own_end is None and getattr(v.simulator, "status", None) is not None:
                v._finish()
        for v in self.vehicles.values():
            v._after_advance()  # LiveRun's: its true-state record trimmed

    def _notify_listeners(self) -> None:
        for v in self.vehicles.values():
            v._notify()

    def _while_paused(self, t: float) -> None:
        for v in self.vehicles.values():
            if v.commander is not None:
                v.commander.process_pending(t)

    def _end_of_run(self) -> tuple[str, str]:
        status = getattr(getattr(self.fleet, "simulator", self.fleet), "status", None)
        return _status(self.fleet), _end_kind(getattr(status, "value", ""))

    def _cancel_pending(self, why: str) -> None:
        for v in self.vehicles.values():
            if v.commander is not None:
                v.commander.cancel_pending(why)

    def _end(self, why: str, kind: str) -> None:
        self.ended = why
        for v in self.vehicles.values():
            if v._own_end is None:  # (one that ended on its own has said why)
                v.events.append(float(self.fleet.t), kind, why)
                v._notify(force=True)


def _status(fleet: Any) -> str:
    sim = getattr(fleet, "simulator", fleet)
    status = getattr(sim, "status", None)
    message = getattr(sim, "message", "")
    if status is None:
        return "ended"
    return f"{getattr(status, 'value', status)}: {message}"


def _without_scripts(config: Any) -> Any:
    """``config`` with no scripted commands: the top-level planner's and each vehicle's own planner's."""
    import dataclasses

    from cufund.scenarios.fleet_schema import VehicleSpec

    planner = config.planner
    if planner is not None and hasattr(planner.params, "script") and planner.params.script:
        config = config.replace(
            planner=dataclasses.replace(planner, params=dataclasses.replace(planner.params, script=()))
        )
    specs = []
    for v in config.vehicles:
        p = v.overrides.get("planner")
        if isinstance(p, dict) and ("script" in p or "script" in (p.get("params") or {})):
            p = {k: val for k, val in p.items() if k != "script"}
            if isinstance(p.get("params"), dict):
                p["params"] = {k: val for k, val in p["params"].items() if k != "script"}
            v = VehicleSpec(v.name, v.start_p_W, v.start_yaw, {**v.overrides, "planner": p})
        specs.append(v)
    return config.replace(vehicles=tuple(specs))

"""A scenario flown live: the simulator in a background thread, paced to the wall clock, commanded from any thread
(what ``cufund serve`` and ``cufund gcs`` run).

    with LiveRun("vehicle", speed=1.0) as run:
        run.submit({"command": "arm"}).result(timeout=2)
        run.submit({"command": "takeoff", "altitude": 1.5})
        print(run.telemetry()["p_W"])

An exception inside a component never escapes the simulation thread: it becomes an ``error`` event, the
component skips that tick and the commander holds (an exception outside components ends the run cleanly, also as
an event). A crash or collision ends the run with a ``crash`` event.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
import traceback
from collections.abc import Callable, Iterable
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.components import Component
from cufund.core.messages import Topics
from cufund.geometry import euler_zyx
from cufund.missions.commander import Commander
from cufund.missions.commands import CommandAck, parse_command
from cufund.missions.controller_params import controller_param_provider
from cufund.missions.events import EventLog
from cufund.scenarios.build import build_simulation
from cufund.scenarios.schema import ScenarioConfig, load_scenario

from .paced_loop import SPEED_MAX, SPEED_MIN, PacedLoop

__all__ = ["SPEED_MAX", "SPEED_MIN", "LiveRun"]

RECORD_HZ = 200.0
"""Rate of the true-state record of a live run [Hz]."""
_KEEP_BLOCKS = 64
"""Record blocks (4096 rows each) a live run keeps."""


def _end_kind(status: str) -> str:
    """The event kind of a run (or a fleet vehicle's run) ending with simulator status ``status``."""
    return "crash" if status in ("crashed", "diverged") else "ended"


def _rpy(q: np.ndarray) -> list[float]:
    """Roll, pitch, yaw [rad] (ZYX Euler angles of body to world)."""
    return list(euler_zyx(q))


def _vec(a: Any) -> list[float] | None:
    return None if a is None else [float(v) for v in np.asarray(a).ravel()]


class _Tap(Component):
    """A truth consumer that keeps the newest message of every topic for readers in other threads."""

    name = "live_tap"
    reads_truth = True

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self.topics: tuple[str, ...] = ()
        self.snapshot: tuple[float | None, dict[str, Any]] = (None, {})
        """(time, newest message by topic), swapped whole: readers in other threads see one instant."""

    @property
    def latest(self) -> dict[str, Any]:
        return self.snapshot[1]

    @property
    def optional_inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return self.topics

    def step(self, t: float, bus: Any) -> None:
        snap = {}
        for topic in self.topics:
            m = bus.latest(topic)
            if m is not None:
                snap[str(topic)] = m
        self.snapshot = (t, snap)


class LiveRun(PacedLoop):
    """Builds ``scenario_or_config`` (a built-in name, a YAML path, a dict or a :class:`ScenarioConfig`, with
    ``overrides`` as for ``cufund run --set``) and runs it in a background thread at ``speed`` x real time
    (``math.inf``: as fast as possible). Starts at once unless ``start=False``. The commander's scripted
    commands (``planner.script``) are dropped unless ``script=True``: a live vehicle waits for its operator.

    ``commander`` is the scenario's :class:`cufund.missions.Commander` (None without one); ``submit(cmd)`` queues
    a command for it and returns a Future of its :class:`CommandAck`; ``telemetry()`` is a JSON-able snapshot;
    ``add_listener(fn, rate_hz)`` calls ``fn(telemetry)`` from the simulation thread at up to ``rate_hz`` (wall
    clock); ``latest(topic)`` is the newest message of a topic (point clouds, ESDF updates); ``events`` is the
    append-only :class:`EventLog`.
    """

    def __init__(
        self,
        scenario_or_config: Any,
        overrides: Iterable[str] | dict[str, Any] = (),
        speed: float = 1.0,
        start: bool = True,
        telemetry_hz: float = 50.0,
        script: bool = False,
        extra_components: Iterable[Component] = (),
    ) -> None:
        self._init_pacing(speed)
        self.config = self._config(scenario_or_config, overrides)
        if not script and self.config.planner is not None and hasattr(self.config.planner.params, "script"):
            # a live vehicle waits for its operator: the scenario's scripted commands are for `cufund run`
            planner = dataclasses.replace(
                self.config.planner, params=dataclasses.replace(self.config.planner.params, script=())
            )
            self.config = self.config.replace(planner=planner)
        self._tap = _Tap(telemetry_hz)
        self.built = build_simulation(self.config, extra_components=(*extra_components, self._tap))
        self.simulator = sim = self.built.simulator
        self._tap.topics = tuple(
            sorted(
                {str(t) for c in sim.components if c is not self._tap for t in c.outputs} | {str(Topics.TRUTH_ODOMETRY)}
            )
        )
        found = [c for c in sim.components if isinstance(c, Commander)]
        self.commander: Commander | None = found[0] if found else None
        self.events: EventLog = (
            self.commander.events
            if self.commander is not None
            else next((e for c in sim.components if isinstance(e := getattr(c, "events", None), EventLog)), EventLog())
        )  # without a commander: the failsafe supervisor's, so its events reach the ground station and MAVLink
        if self.commander is not None:  # the controllers' gains by PX4 name, through get_params / set_param
            self.commander.param_providers.append(controller_param_provider(sim.components))
        self._errors: dict[str, int] = {}
        for c in sim.components:
            self._guard(c)
        self._listeners: list[list[Any]] = []
        self._listeners_lock = threading.Lock()
        vp = self.built.context.vehicle
        self._max_thrust = 4.0 * vp.k_f * vp.rotor_speed_max**2
        self._estimated = self.config.estimator is not None
        # a live run may last hours: keep no message history and the true state at RECORD_HZ only (its crash and
        # divergence checks run at the recorded nodes), trimmed to the last ~20 minutes
        sim.record_topics = ()
        ratio = sim.physics_rate_hz / RECORD_HZ
        if ratio == int(ratio) and ratio >= 1:
            sim.record_period = int(ratio)
        sim.reset()
        if start:
            self.start()

    @staticmethod
    def _config(src: Any, overrides: Any) -> ScenarioConfig:
        if isinstance(src, ScenarioConfig):
            return src.with_overrides(overrides) if overrides else src
        if isinstance(src, dict):
            return (
                ScenarioConfig.from_dict(src).with_overrides(overrides) if overrides else ScenarioConfig.from_dict(src)
            )
        if isinstance(src, (str, Path)):
            return load_scenario(src, overrides)
        raise TypeError(
            f"scenario_or_config must be a scenario name, a path, a dict or a ScenarioConfig, got {type(src).__name__}"
        )

    def _guard(self, c: Component) -> None:
        """Wraps ``c.step`` so that an exception becomes an event (and the commander holds) instead of a crash."""
        step = c.step
        name = getattr(c, "name", "") or type(c).__name__

        def guarded(t: float, bus: Any) -> None:
            try:
                step(t, bus)
            except Exception as e:
                n = self._errors.get(name, 0) + 1
                self._errors[name] = n
                if n == 1 or n in (10, 100, 1000) or n % 10000 == 0:
                    tb = traceback.extract_tb(e.__traceback__)[-1]
                    self.events.append(
                        t,
                        "error",
                        f"{name}: {type(e).__name__}: {e} ({Path(tb.filename).name}:{tb.lineno}; {n} so far)",
                        component=name,
                        count=n,
                    )
                cmd = self.commander
                if n == 1 and cmd is not None and c is not cmd and cmd.airborne and cmd.mode != "hold":
                    cmd.submit({"command": "hold"})

        c.step = guarded  # type: ignore[method-assign]

    # -- control of the run (start, pause, resume, set_speed, stop: PacedLoop's) ---------------------------
    def wait_until(self, predicate: Callable[[dict[str, Any]], bool], timeout: float) -> bool:
        """Polls ``predicate(telemetry())`` until it holds (True) or ``timeout`` wall seconds pass (False)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate(self.telemetry()):
                return True
            if self.ended is not None:
                return bool(predicate(self.telemetry()))
            time.sleep(0.01)
        return False

    # -- commands ----------------------------------------------------------------------------------------------
    def submit(self, cmd: Any) -> Future:
        """Queues ``cmd`` for the commander (ValueError at once for malformed input); a Future of its ack."""
        command = parse_command(cmd)
        if self.commander is None or self.ended is not None:
            fut: Future = Future()
            why = "no commander in this scenario" if self.commander is None else f"the run has ended ({self.ended})"
            fut.set_result(CommandAck(command.command, "unsupported" if self.commander is None else "failed", why))
            return fut
        fut = self.commander.submit(command)
        with self._wake:  # the simulation thread may be sleeping until the wall clock catches up: go on now
            self._wake.notify_all()
        return fut

    # -- the simulation thread (PacedLoop's loop, with these hooks) ----------------------------------------------
    def _sim_t(self) -> float:
        return float(self.simulator.t)

    def _advance_to(self, t: float) -> bool:
        return bool(self.simulator.advance_to(t))

    def _after_advance(self) -> None:
        rows = getattr(self.simulator, "_rows", None)
        if rows is not None and len(rows) > _KEEP_BLOCKS:
            del rows[: len(rows) - _KEEP_BLOCKS]

    def _notify_listeners(self) -> None:
        self._notify()

    def _while_paused(self, t: float) -> None:
        if self.commander is not None:
            self.commander.process_pending(t)

    def _end_of_run(self) -> tuple[str, str]:
        sim = self.simulator
        status = sim.status.value if sim.status is not None else ""
        return f"{status or 'ended'}: {sim.message}", _end_kind(status)

    def _cancel_pending(self, why: str) -> None:
        if self.commander is not None:
            self.commander.cancel_pending(why)

    def _end(self, why: str, kind: str) -> None:
        self.ended = why
        self.events.append(self.simulator.t, kind, why)
        self._notify(force=True)

    def _notify(self, force: bool = False) -> None:
        now = time.perf_counter()
        with self._listeners_lock:
            due = [entry for entry in self._listeners if force or now >= entry[2]]
            for entry in due:
                entry[2] = now + 1.0 / entry[1]
        if not due:
            return
        snap = self.telemetry()
        for fn, _, _ in due:
            try:
                fn(snap)
            except Exception as e:
                self.events.append(self.simulator.t, "warning", f"telemetry listener failed: {type(e).__name__}: {e}")

    def add_listener(self, fn: Callable[[dict[str, Any]], None], rate_hz: float = 30.0) -> Callable[[], None]:
        """Calls ``fn(telemetry)`` from the simulation thread at up to ``rate_hz`` [Hz, wall clock]. Returns a
        function that removes it."""
        if not callable(fn):
            raise TypeError("fn must be callable: fn(telemetry_dict)")
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) or not (0 < rate_hz <= 1000):
            raise ValueError(f"rate_hz must be a number in (0, 1000] [Hz], got {rate_hz!r}")
        entry = [fn, float(rate_hz), 0.0]
        with self._listeners_lock:
            self._listeners.append(entry)

        def remove() -> None:
            with self._listeners_lock:
                if entry in self._listeners:
                    self._listeners.remove(entry)

        return remove

    # -- what is seen ------------------------------------------------------------------------------------------
    def latest(self, topic: str) -> Any:
        """The newest message on ``topic`` at the last telemetry tick (None if none)."""
        return self._tap.latest.get(str(topic))

    def telemetry(self, events_since: int | None = None) -> dict[str, Any]:
        """A JSON-able snapshot: time, command state, vehicle state (what the vehicle believes: the estimate when
        an estimator runs), the true state and the errors against it (this is a truth consumer), setpoint,
        thrust margin, estimator health, mission progress, and the events from index ``events_since``."""
        t_snap, snap = self._tap.snapshot
        truth = snap.get(str(Topics.TRUTH_ODOMETRY))
        est = snap.get(str(Topics.ESTIMATE)) if self._estimated else None
        state = est if self._estimated else truth
        sp = snap.get(str(Topics.TRAJECTORY_SETPOINT))
        tt = snap.get(str(Topics.THRUST_TORQUE_SETPOINT))
        t = float(self.simulator.t) if t_snap is None else float(t_snap)  # the snapshot's time
        out: dict[str, Any] = {
            "t": t,
            "sim_t": float(self.simulator.t),
            "speed": None if self._speed == math.inf else self._speed,
            "paused": self._paused,
            "ended": self.ended,
        }
        out["real_time_factor"] = self.real_time_factor()  # simulated s per wall s over the last ~2 s
        c = self.commander
        if c is not None:
            out.update(
                {
                    "mode": c.mode,
                    "armed": c.armed,
                    "landed": c.landed,
                    "flight_mode": c.flight_mode.value,
                    "controller": c.controller,
                    "home_p_W": _vec(c.home_p_W) if np.all(np.isfinite(c.home_p_W)) else None,
                    "target_p_W": _vec(c.target_p_W) if np.all(np.isfinite(c.target_p_W)) else None,
                    "mission": {
                        "current": c.mission_current,
                        "count": len(c.mission),
                        "items": [list(it.p_W) for it in c.mission],
                    },
                    "plan_W": [list(p) for p in c.plan_W],
                    "message": c.message,
                }
            )
        else:
            out.update(
                {
                    "mode": "external",
                    "armed": True,
                    "landed": False,
                    "flight_mode": "position",
                    "controller": self.config.controller.kind if self.config.controller else None,
                }
            )
        if state is not None:
            out.update(
                {
                    "p_W": _vec(state.p_W),
                    "v_W": _vec(state.v_W),
                    "q_WB": _vec(state.q_WB),
                    "w_B": _vec(state.w_B),
                    "rpy": _rpy(state.q_WB),
                }
            )
        if truth is not None:
            out.update({"truth_p_W": _vec(truth.p_W), "truth_v_W": _vec(truth.v_W), "truth_q_WB": _vec(truth.q_WB)})
        out["setpoint_p_W"] = _vec(sp.p_W) if sp is not None else None
        out["tracking_error_m"] = (
            float(np.linalg.norm(truth.p_W - sp.p_W)) if sp is not None and truth is not None else None
        )
        out["odometry_error_m"] = (
            float(np.linalg.norm(truth.p_W - est.p_W)) if est is not None and truth is not None else None
        )
        out["thrust_margin"] = float(1.0 - tt.thrust / self._max_thrust) if tt is not None else None
        bat = snap.get(str(Topics.BATTERY))  # the power module's reading (vehicle.battery), else absent
        if bat is not None:
            out["battery"] = {
                "voltage_v": float(bat.voltage_v),
                "current_a": float(bat.current_a),
                "remaining": float(bat.remaining),
                "consumed_mah": float(bat.consumed_mah),
                "cells": int(bat.cells),
            }
        if self._estimated:
            out["estimator"] = {
                "ok": est is not None and bool(np.all(np.isfinite(est.p_W))) and t - est.t < 0.5,
                "age_s": None if est is None else t - float(est.t),
            }
        else:
            out["estimator"] = {"ok": True, "age_s": 0.0, "source": "ground truth"}
        out["events_count"] = len(self.events)
        if events_since is not None:
            out["events"] = self.events.since(events_since)
        return out

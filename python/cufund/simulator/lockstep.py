"""The lockstep simulator: physics at a fixed rate, components on a deterministic event schedule.

Physics steps at ``physics_rate_hz`` on its own grid; an event (a component's run, or a message with latency
becoming visible) that falls between two physics nodes splits that step, so every event happens at its exact time
(to the nanosecond, see :mod:`cufund.core.scheduler`). A run is advanced from outside with :meth:`Simulator.advance_to`
or :meth:`Simulator.step` (lockstep for MAVLink, a ground station or a sweep worker); :meth:`Simulator.run` is
:meth:`reset` plus ``advance_to``. Same components, same seed: bit-identical runs.
"""

from __future__ import annotations

import enum
import math
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from cufund.core.bus import Bus, BusView
from cufund.core.components import Component, Estimator, _StateUser
from cufund.core.messages import ActuatorCommand, Odometry, Topics
from cufund.core.scheduler import NS, EventClock, ScheduleError, rate_fraction, seconds_to_ns, topological_order
from cufund.core.topics import is_truth
from cufund.vehicle.quadrotor import Quadrotor
from cufund.worlds.collision import CollisionChecker, Contact

__all__ = ["RunStatus", "SimulationResult", "Simulator"]


class RunStatus(enum.Enum):
    """How a run ended."""

    COMPLETED = "completed"
    """The ``done`` condition held (or, without one, the duration elapsed)."""
    TIMEOUT = "timeout"
    """The duration elapsed before the ``done`` condition held."""
    CRASHED = "crashed"
    """The vehicle hit the ground too fast, landed upside down, or collided with a world object."""
    DIVERGED = "diverged"
    """The state became non-finite or left physical bounds."""
    ABORTED = "aborted"
    """A component ended the run (e.g. a mission that aborted and landed), with its reason."""


@dataclass
class SimulationResult:
    """What a run returns. ``states`` holds ground truth sampled every ``record_period`` physics steps:
    ``t`` (N,), ``p_W`` (N, 3), ``v_W`` (N, 3), ``q_WB`` (N, 4), ``w_B`` (N, 3), ``rotor_speeds`` (N, 4).
    ``topics`` maps each recorded topic to its messages as arrays (one per message field, stacked; a field
    whose shape varies between messages, like a LiDAR frame's points, is a list)."""

    status: RunStatus
    sim_time_s: float
    wall_time_s: float
    states: dict[str, np.ndarray]
    topics: dict[str, dict[str, np.ndarray | list[Any]]] = field(default_factory=dict)
    recordings: dict[str, dict[str, Any]] = field(default_factory=dict)
    """``Recorder`` components' histories, by component name."""
    message: str = ""
    """Why the run ended, in words."""
    contact: Contact | None = None
    """For a run that CRASHED into a world object: the contact (object, label, point, normal, depth)."""
    dropped: dict[str, int] = field(default_factory=dict)
    """Messages dropped from full subscription queues, by ``component:topic`` (empty when none was)."""
    component_seconds: dict[str, float] = field(default_factory=dict)
    """Wall time spent in each component's ``step`` [s] (``physics``: the integrator)."""

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf


def _stack(messages: list[Any]) -> dict[str, np.ndarray | list[Any]]:
    """Each message field stacked into one array along a new first axis; a field whose values differ in
    shape from message to message (e.g. the points of LiDAR frames) stays a list of its values."""
    if not messages:
        return {}
    out: dict[str, np.ndarray | list[Any]] = {}
    for f in fields(messages[0]):
        values = [getattr(m, f.name) for m in messages]
        if isinstance(values[0], enum.Enum):
            values = [v.value for v in values]
        shapes = {
            v.shape if v.__class__ is np.ndarray else () if v is None or v.__class__ in _SCALARS else np.shape(v)
            for v in values
        }
        out[f.name] = np.asarray(values) if len(shapes) == 1 and _stackable(values[0]) else values
    return out


_SCALARS = frozenset((float, int, bool, str))  # np.shape(v) == () without asking numpy


def _stackable(value: Any) -> bool:
    return value is None or isinstance(value, (int, float, bool, str, np.ndarray, np.generic))


def _joined(views: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """Views into one buffer (the vehicle's C++ state) merged where each ends where the next begins, so that
    copying them out takes fewer numpy calls. Same values, same order."""
    out = [views[0]]
    for v in views[1:]:
        last = out[-1]
        if (
            last.dtype == v.dtype
            and last.ndim == v.ndim == 1
            and last.strides == v.strides == (v.itemsize,)
            and v.ctypes.data == last.ctypes.data + last.nbytes
        ):
            # the two are adjacent in memory: one view over both (the first's buffer keeps it alive)
            out[-1] = np.lib.stride_tricks.as_strided(last, (len(last) + len(v),), last.strides, writeable=False)
        else:
            out.append(v)
    return tuple(out)


class _DeferredTruth(Odometry):
    """Ground truth at one node, built on the first read of a state field: what ``done(t, truth)`` receives at a
    node where no snapshot was published (most ``done`` conditions test the time first and read the state only
    near the end). A ``done`` that keeps it gets it built before the state moves on (see ``_node_checks``)."""

    __slots__ = ("_value", "_sim")
    _value: Odometry | None
    _sim: Any

    def _resolve(self) -> Odometry:
        value = self._sim._snapshot(self.t)
        object.__setattr__(self, "_value", value)
        return value


def _deferred_field(name: str) -> property:
    def get(self: _DeferredTruth) -> Any:
        value = self._value
        if value is None:
            value = self._resolve()
        return getattr(value, name)

    return property(get, doc=f"Odometry.{name}, built on first read.")


for _f in fields(Odometry):
    if _f.name != "t":
        setattr(_DeferredTruth, _f.name, _deferred_field(_f.name))


class _Slot:
    """A component as scheduled: its clock, bus handle and time spent."""

    __slots__ = ("component", "name", "clock", "view", "run", "seconds", "reads_truth")

    def __init__(self, component: Component, name: str, clock: EventClock, view: BusView) -> None:
        self.component, self.name, self.clock, self.view = component, name, clock, view
        self.run = component.step
        self.seconds = 0.0
        self.reads_truth = str(Topics.TRUTH_ODOMETRY) in view.inputs
        """It may read ground truth: the snapshot is published before it runs."""


class Simulator:
    """Advances ``vehicle`` at ``physics_rate_hz`` and runs the added components on their schedules.

    The vehicle's rotor-speed input is the latest visible :class:`~cufund.core.messages.ActuatorCommand` on
    ``Topics.ACTUATOR_COMMAND`` (held until the next one; before the first, the rotor speeds at the start of the
    run). Ground truth (with the true accelerations of the last physics step, which inertial sensors read) is
    published on ``Topics.TRUTH_ODOMETRY`` at every instant where a component runs. Set the initial state through
    ``vehicle`` (e.g. ``vehicle.hover(p_W)``) before :meth:`reset` / :meth:`run`.

    Args:
        vehicle: the plant.
        physics_rate_hz: physics steps per second (the grid the integrator steps on between events).
        record_rate_hz: ground-truth sampling rate for the result (defaults to the physics rate; it must divide
            it: samples are taken at physics nodes).
        record_topics: topics whose every message is kept in memory for the result.
        collision: checks the vehicle against a world's meshes (build it with ``ignore_labels=("floor",
            "ground")`` to leave landing to the dynamics' ground plane).
        collision_rate_hz: how often the collision check runs (must divide the physics rate).
        vehicle: the plant; None runs the components on the clock without physics or ground truth (e.g. an
            estimator fed by a :class:`cufund.logs.LogPlayer`).
        logger: receives every visible message (``write(topic, message, log_time_ns, publish_time_ns)``), e.g. a
            :class:`cufund.logs.McapLogger`; ground truth is logged at ``log_truth_rate_hz``.
    """

    def __init__(
        self,
        vehicle: Quadrotor | None,
        physics_rate_hz: float = 1000.0,
        record_rate_hz: float | None = None,
        record_topics: Iterable[str] = (),
        collision: CollisionChecker | None = None,
        collision_rate_hz: float = 250.0,
        logger: Any = None,
    ) -> None:
        if vehicle is not None and not isinstance(vehicle, Quadrotor):
            raise TypeError(f"vehicle must be a cufund.Quadrotor (or None: no physics), got {type(vehicle).__name__}")
        self._physics_rate = rate_fraction("physics_rate_hz", physics_rate_hz)
        self.vehicle = vehicle
        self.physics_rate_hz = float(physics_rate_hz)
        self.record_period = self._nodes_per("record_rate_hz", record_rate_hz or physics_rate_hz)
        self.record_topics = tuple(record_topics)
        if collision is not None and not isinstance(collision, CollisionChecker):
            raise TypeError(f"collision must be a cufund.worlds.CollisionChecker, got {type(collision).__name__}")
        self.collision = collision
        """The vehicle's shape against a world: any penetration ends the run CRASHED with the contact."""
        self.collision_period = self._nodes_per("collision_rate_hz", collision_rate_hz)
        self.logger = logger
        self.start_time = 0.0
        """Without a vehicle: the simulated time at which a run starts [s]."""
        self.components: list[Component] = []
        self.crash_speed = 1.0
        """Downward speed at ground contact above which a run counts as crashed [m/s]."""
        self.max_distance = 1e4
        """Distance from the origin beyond which a run counts as diverged [m]."""
        self.max_body_rate = 1e3
        """Body rate beyond which a run counts as diverged [rad/s]."""
        self._started = False

    def _nodes_per(self, name: str, rate_hz: float) -> int:
        """Physics nodes per sample of an activity that runs on the physics grid."""
        ratio = self._physics_rate / rate_fraction(name, rate_hz)
        if ratio.denominator != 1 or ratio < 1:
            raise ValueError(
                f"{name} must divide the physics rate {self.physics_rate_hz:g} Hz exactly, got {float(rate_hz):g} Hz"
            )
        return int(ratio)

    def add(self, component: Component) -> Component:
        """Attaches ``component`` (its place within an instant follows from its declared inputs and outputs).
        Returns it."""
        if not isinstance(component, Component):
            raise TypeError(
                f"component must implement cufund.core.components.Component, got {type(component).__name__}"
            )
        label = getattr(component, "name", "") or type(component).__name__
        rate_fraction(f"{label}.rate_hz", component.rate_hz)
        seconds_to_ns(f"{label}.phase_s", component.phase_s)
        seconds_to_ns(f"{label}.latency_s", component.latency_s)
        self.components.append(component)
        return component

    # -- wiring ------------------------------------------------------------------------------------------------
    @property
    def estimators(self) -> list[Estimator]:
        return [c for c in self.components if isinstance(c, Estimator)]

    def _resolve_state_topics(self) -> None:
        estimators = self.estimators
        for c in self.components:
            if not isinstance(c, _StateUser) and not hasattr(c, "active_state_topic"):
                continue
            state_topic = getattr(c, "state_topic", None)
            if state_topic is not None:
                c.active_state_topic = state_topic
            elif len(estimators) == 1:
                c.active_state_topic = estimators[0].topic
            elif not estimators:
                c.active_state_topic = Topics.TRUTH_ODOMETRY
            else:
                raise ValueError(
                    f"{type(c).__name__}.state_topic must be set when several estimators are attached "
                    f"({', '.join(e.topic for e in estimators)})"
                )
            on_estimate = getattr(c, "use_estimator", None)
            if on_estimate is not None:
                on_estimate(bool(estimators))

    def _names(self) -> list[str]:
        names: list[str] = []
        seen: dict[str, int] = {}
        for c in self.components:
            base = getattr(c, "name", type(c).__name__) or type(c).__name__
            k = seen.get(base, 0)
            seen[base] = k + 1
            names.append(base if k == 0 else f"{base}#{k + 1}")
        return names

    def wiring(self) -> list[str]:
        """Problems of the component graph, one sentence each (empty when every required input has a publisher
        and, with an estimator, no flight software reads ground truth). Resolves the state topics first."""
        self._resolve_state_topics()
        names = self._names()
        published = {str(Topics.TRUTH_ODOMETRY)} if self.vehicle is not None else set()
        for c in self.components:
            published.update(str(t) for t in c.outputs)
        problems = []
        deny = bool(self.estimators)
        for name, c in zip(names, self.components, strict=True):
            for topic in c.inputs:
                if str(topic) not in published:
                    problems.append(f"{name} needs {topic}; nothing publishes it")
            if deny and not c.reads_truth:
                for topic in (*c.inputs, *c.optional_inputs):
                    if is_truth(str(topic)):
                        problems.append(f"{name} reads ground truth ({topic}) although an estimator is configured")
        return problems

    # -- running -----------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Starts a run at the vehicle's current state and time: resets every component, orders them, opens the
        bus. Raises ValueError (naming the components and topics) for an unsatisfied input, a truth read by
        flight software with an estimator configured, or a zero-latency cycle."""
        problems = self.wiring()
        if problems:
            raise ValueError("; ".join(problems))
        names = self._names()
        latencies = [seconds_to_ns(f"{n}.latency_s", c.latency_s) for n, c in zip(names, self.components, strict=True)]
        order = topological_order(
            names,
            [(*c.inputs, *c.optional_inputs) for c in self.components],
            [c.outputs for c in self.components],
            latencies,
        )
        self.t_start_ns = round(self.vehicle.t * NS) if self.vehicle is not None else round(self.start_time * NS)
        self.bus = Bus(self.record_topics, logger=self.logger)
        self.bus.now_ns = self.t_start_ns
        deny = bool(self.estimators)
        self._slots: list[_Slot] = []
        for i in order:
            c, name = self.components[i], names[i]
            c.reset()
            phase = seconds_to_ns(f"{name}.phase_s", c.phase_s)
            rate = rate_fraction(f"{name}.rate_hz", c.rate_hz)
            if phase * rate >= NS:
                raise ScheduleError(f"{name}.phase_s must be less than its period 1 / rate_hz, got {c.phase_s!r}")
            view = BusView(
                self.bus,
                name,
                (*c.inputs, *c.optional_inputs, Topics.TRUTH_ODOMETRY)
                if c.reads_truth
                else (*c.inputs, *c.optional_inputs),
                c.outputs,
                latencies[i],
                deny_truth=deny and not c.reads_truth,
            )
            c.setup(view)
            self._slots.append(_Slot(c, name, EventClock(rate, phase, self.t_start_ns), view))
        self._physics = EventClock(self._physics_rate, 0, self.t_start_ns)
        self._physics.advance()
        self._node = 0  # physics nodes passed since the start of the run
        self._at_node = True
        self._processed_ns = -1
        self._truth_at: tuple[int, Odometry | None] = (-1, None)
        self._now_ns = self.t_start_ns
        if self.vehicle is not None:
            self._state = s = self.vehicle.state  # views into the C++ state, valid for the vehicle's lifetime
            self._truth_views = _joined(
                (s.p, s.v, s.q, s.w, self.vehicle.accel_W, self.vehicle.alpha_B, s.rotor_speeds)
            )
            self._row_views = _joined((s.p, s.v, s.q, s.w, s.rotor_speeds))
            self._cmd: np.ndarray | None = s.rotor_speeds.copy()
            self._ground_plane = bool(self.vehicle.params.ground_plane)
        else:
            self._cmd = None
        self._rows: list[np.ndarray] = []
        self._block = np.empty((4096, 18))
        self._n_block = 0
        self.status: RunStatus | None = None
        self.message = ""
        self.contact: Contact | None = None
        self._wall = 0.0
        self._physics_seconds = 0.0
        self._started = True

    @property
    def schedule(self) -> list[dict[str, Any]]:
        """The components in the order they run within an instant (after :meth:`reset`), with their timing."""
        if not self._started:
            raise RuntimeError("no run: call reset() first")
        return [
            {
                "name": s.name,
                "rate_hz": float(s.component.rate_hz),
                "phase_s": float(s.component.phase_s),
                "latency_s": float(s.component.latency_s),
            }
            for s in self._slots
        ]

    @property
    def views(self) -> dict[str, BusView]:
        """Each component's bus handle by name (its ``reads`` tell which topics it read)."""
        return {s.name: s.view for s in self._slots}

    @property
    def t(self) -> float:
        """The current simulated time [s]."""
        if self._started:
            return self._now_ns / NS
        return self.vehicle.t if self.vehicle is not None else self.start_time

    @property
    def finished(self) -> bool:
        return self._started and self.status is not None

    def stop(self, status: RunStatus, message: str) -> None:
        """Ends the run now with ``status`` (a component may call it, e.g. a mission that aborted)."""
        if self.status is None:
            self.status, self.message = status, message

    def _snapshot(self, t: float) -> Odometry:
        """Ground truth now, with the true accelerations of the last physics step and the rotor speeds (one
        read-only buffer)."""
        x = np.concatenate(self._truth_views)
        x.setflags(write=False)
        return Odometry.trusted(t, x[0:3], x[3:6], x[6:10], x[10:13], x[13:16], x[16:19], x[19:23])

    def _write_row(self, t: float) -> np.ndarray:
        if self._n_block == len(self._block):
            self._rows.append(self._block)
            self._block = np.empty((4096, 18))
            self._n_block = 0
        row = self._block[self._n_block]
        self._n_block += 1
        row[0] = t
        views = self._row_views
        if len(views) == 1:  # the state's rows lie next to each other: one copy
            row[1:18] = views[0]
        else:
            row[1:4], row[4:7], row[7:11], row[11:14], row[14:18] = views
        return row

    def step(self, done: Callable[[float, Odometry], bool] | None = None) -> bool:
        """Advances one physics step (events inside it included). Returns False once the run has ended."""
        if not self._started:
            self.reset()
        return self.advance_to(self._physics.next_ns / NS, done)

    def advance_to(
        self, t: float, done: Callable[[float, Odometry], bool] | None = None, progress: bool = False
    ) -> bool:
        """Simulates up to time ``t`` [s], continuing the current run (starting one with :meth:`reset` if none is
        open). Time stops at the last physics node or event at or before ``t`` (a physics step is never split for
        where a call ends, so any sequence of calls gives the same run, bit for bit); events at the time reached
        run at the next call. ``done(t, truth)`` is checked at every
        ground-truth record; when it holds the run ends COMPLETED. Returns False once the run has ended."""
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
            raise ValueError(f"t must be a finite time [s], got {t!r}")
        if not self._started:
            self.reset()
        if self.status is not None:
            return False
        end_ns = round(t * NS)
        if end_ns < self._now_ns:
            raise ValueError(f"t must not be before the simulator's time {self.t:.9f} s, got {t!r}")
        wall0 = time.perf_counter()
        try:
            self._advance(end_ns, done, progress)
        finally:
            self._wall += time.perf_counter() - wall0
        return self.status is None

    def _advance(
        self,
        end_ns: int,
        done: Callable[[float, Odometry], bool] | None,
        progress: bool,
        defer: Callable[[float, Any], None] | None = None,
    ) -> None:
        """The run up to ``end_ns``; with ``defer``, it returns after the first physics step, and hands that step
        ``(dt, rotor_speed_cmd)`` to ``defer`` instead of taking it when the plant's step is the bare C++ step (the
        fleet's batched physics, :mod:`cufund.simulator.fleet`, integrates every vehicle's in one call); a plant
        stepped through Python (a wind function, a surface probe) takes it itself."""
        quad, bus, slots, physics = self.vehicle, self.bus, self._slots, self._physics
        truth_topic, actuator = Topics.TRUTH_ODOMETRY, str(Topics.ACTUATOR_COMMAND)
        latest, next_visible, deliver = bus.latest, bus.next_visible_ns, bus.deliver
        cmd: Any = self._cmd  # not None whenever there is a vehicle to step
        now, at_node = self._now_ns, self._at_node
        start_ns, span = now, max(end_ns - now, 1)
        last_bar: float = -1
        perf = time.perf_counter
        snapshot, record = self._snapshot, self._node_checks
        # Ground truth is published at an instant before the first component that may read it. When nothing else
        # observes the topic (no log, no recording, no subscription), instants where only flight software runs
        # (which reads the estimate once one is attached) skip the snapshot: no reader could tell.
        always_truth = bus.has_consumer(truth_topic)
        # Quadrotor.step without its Python layer (quad.fast_step) unless step is overridden
        fast = quad is not None and quad.step == Quadrotor.step.__get__(quad)
        physics_seconds = self._physics_seconds
        processed = self._processed_ns
        # the physics clock's arithmetic inlined (EventClock.advance): t_k = start + k * NS * den // num
        p_start, p_num, p_den = physics.start_ns, physics.num, physics.den
        p_step = NS * p_den
        p_k, p_next = physics.k, physics.next_ns
        check_nodes = quad is not None
        next_event = self._next_event()
        try:
            while now < end_ns:
                if processed != now:  # events and node checks at `now`, once
                    processed = self._processed_ns = now
                    if now >= next_event:
                        bus.now_ns = now
                        visible = next_visible()
                        if visible is not None and visible <= now:
                            bus.release(now)
                        t = now / NS
                        truth = None
                        next_event = math.inf
                        for s in slots:
                            clock = s.clock
                            if clock.next_ns == now:
                                if truth is None and quad is not None and (always_truth or s.reads_truth):
                                    truth = snapshot(t)
                                    self._truth_at = (now, truth)
                                    deliver(truth_topic, truth, now, now)
                                w0 = perf()
                                s.run(t, s.view)
                                s.seconds += perf() - w0
                                clock.advance()
                            if clock.next_ns < next_event:
                                next_event = clock.next_ns
                        visible = next_visible()
                        if visible is not None and visible < next_event:
                            next_event = visible
                        act: ActuatorCommand | None = latest(actuator)
                        if act is not None:
                            cmd = act.rotor_speeds
                        if self.status is not None:  # a component stopped the run
                            if quad is not None:
                                self._write_row(t)
                            break
                    if at_node and check_nodes and record(now, done):
                        break
                target = p_next if p_next < next_event else next_event
                if target > end_ns:  # stop on the grid: a step is never split for where a call ends
                    break
                if quad is not None:
                    w0 = perf()
                    core_step = quad.fast_step if fast else None  # None while a wind function is set
                    if core_step is not None:
                        if defer is not None and core_step is quad._step:
                            defer((target - now) / NS, cmd)
                        else:
                            core_step((target - now) / NS, cmd, 1)
                    else:
                        quad.step((target - now) / NS, cmd)
                    physics_seconds += perf() - w0
                now = target
                at_node = now == p_next
                if at_node:
                    self._node += 1
                    p_k += 1
                    p_next = p_start + (p_k * p_step) // p_num
                if progress:
                    bar = (400 * (now - start_ns)) // span
                    if bar != last_bar:
                        last_bar = bar
                        chars = int(bar) // 10
                        sys.stderr.write(f"\r[{'#' * chars}{'.' * (40 - chars)}] {now / NS:7.2f} s")
                        sys.stderr.flush()
                if defer is not None:
                    break
        finally:
            physics.k, physics.next_ns = p_k, p_next
            self._physics_seconds = physics_seconds
            self._now_ns, self._cmd, self._at_node = now, cmd, at_node
        if progress:  # the run ended or reached end_ns: a full bar, also when it ended early (landed, stopped)
            early = "" if now >= end_ns or self.status is None else " (ended early)"
            sys.stderr.write(f"\r[{'#' * 40}] {now / NS:7.2f} s{early}\n")
            sys.stderr.flush()

    def _next_event(self) -> float:
        """The next instant at which a component runs or a message becomes visible [ns]."""
        nxt = min([s.clock.next_ns for s in self._slots], default=math.inf)
        pending = self.bus.next_visible_ns()
        return pending if pending is not None and pending < nxt else nxt

    def _node_checks(self, now: int, done: Callable[[float, Odometry], bool] | None) -> bool:
        """What happens at a physics node: collision check, state record, divergence and ``done`` checks. True
        when the run ends here."""
        node = self._node
        t = now / NS
        if self.collision is not None and node % self.collision_period == 0:
            state = self._state
            hit = self.collision.check(state.p, state.q)
            if hit is not None and hit.distance < 0.0:
                self.contact = hit
                self.status = RunStatus.CRASHED
                self.message = (
                    f"collided with {hit.label!r} (object {hit.object_id}) at ({hit.point_W[0]:.3f}, "
                    f"{hit.point_W[1]:.3f}, {hit.point_W[2]:.3f}) m at t = {t:.3f} s"
                )
                self._write_row(t)
                return True
        if node % self.record_period:
            return False
        row = self._write_row(t)
        x = row.tolist()  # Python floats: cheaper to compare than numpy scalars
        d, r = self.max_distance, self.max_body_rate
        # the common case (nothing wrong) decided here; _check says what is wrong otherwise
        if (
            not math.isfinite(sum(x))
            or abs(x[1]) > d
            or abs(x[2]) > d
            or abs(x[3]) > d
            or abs(x[11]) > r
            or abs(x[12]) > r
            or abs(x[13]) > r
            or (x[3] <= 0.05 and self._ground_plane)
        ):
            bad = self._check(row)
            if bad is not None:
                self.status, self.message = bad
                return True
        if done is not None:
            at, truth = self._truth_at
            if at != now:
                truth = object.__new__(_DeferredTruth)
                object.__setattr__(truth, "t", t)
                object.__setattr__(truth, "_value", None)
                object.__setattr__(truth, "_sim", self)
                finished = done(t, truth)
                if truth._value is None and sys.getrefcount(truth) > 2:  # kept by done: build it while it is true
                    object.__setattr__(truth, "_value", self._snapshot(t))
            else:
                assert truth is not None  # published at this node
                finished = done(t, truth)
            if finished:
                self.status, self.message = RunStatus.COMPLETED, "done condition met"
                return True
        return False

    def result(self) -> SimulationResult:
        """The run so far: recorded states and topics, status (COMPLETED if still open and no ``done`` given)."""
        if not self._started:
            raise RuntimeError("no run: call reset(), advance_to() or run() first")
        h = np.concatenate([*self._rows, self._block[: self._n_block]]) if self._rows else self._block[: self._n_block]
        states = {
            "t": h[:, 0],
            "p_W": h[:, 1:4],
            "v_W": h[:, 4:7],
            "q_WB": h[:, 7:11],
            "w_B": h[:, 11:14],
            "rotor_speeds": h[:, 14:18],
        }
        topics = {str(topic): _stack(self.bus.recorded(topic)) for topic in self.record_topics}
        recordings = {
            s.name: s.component.histories()
            for s in self._slots
            if hasattr(s.component, "histories") and callable(s.component.histories)
        }
        status = self.status or RunStatus.COMPLETED
        seconds = {s.name: s.seconds for s in self._slots}
        seconds["physics"] = self._physics_seconds
        return SimulationResult(
            status=status,
            sim_time_s=(self._now_ns - self.t_start_ns) / NS,
            wall_time_s=self._wall,
            states=states,
            topics=topics,
            recordings=recordings,
            message=self.message or "duration elapsed",
            contact=self.contact,
            dropped=self.bus.dropped(),
            component_seconds=seconds,
        )

    def run(
        self, duration: float, done: Callable[[float, Odometry], bool] | None = None, progress: bool = False
    ) -> SimulationResult:
        """Simulates up to ``duration`` [s] from the vehicle's current state and time (a new run).

        ``done(t, truth)`` is checked at every ground-truth record; when it holds the run ends COMPLETED (without
        one, the run ends COMPLETED when the duration elapses; with one, TIMEOUT). ``progress`` draws a progress
        bar on stderr.
        """
        if (
            isinstance(duration, bool)
            or not isinstance(duration, (int, float))
            or not math.isfinite(duration)
            or duration <= 0
        ):
            raise ValueError(f"duration must be a finite number > 0 [s], got {duration!r}")
        self.reset()
        self.advance_to(self.t_start_ns / NS + duration, done, progress)
        if self.status is None and self._at_node and self.vehicle is not None:
            self._node_checks(self._now_ns, done)  # the last node: recorded, checked
        if self.status is None:
            self.status = RunStatus.COMPLETED if done is None else RunStatus.TIMEOUT
            self.message = "duration elapsed"
        return self.result()

    def _check(self, row: np.ndarray) -> tuple[RunStatus, str] | None:
        row = row.tolist()  # Python floats: cheaper to compare than numpy scalars
        if not math.isfinite(sum(row)):
            return RunStatus.DIVERGED, f"non-finite state at t = {row[0]:.3f} s"
        d, r = self.max_distance, self.max_body_rate
        if abs(row[1]) > d or abs(row[2]) > d or abs(row[3]) > d:
            return RunStatus.DIVERGED, f"vehicle left the {d:g} m bounds at t = {row[0]:.3f} s"
        if abs(row[11]) > r or abs(row[12]) > r or abs(row[13]) > r:
            return RunStatus.DIVERGED, f"body rate above {r:g} rad/s at t = {row[0]:.3f} s"
        if self._ground_plane and row[3] <= 0.05:
            # body z axis's world z component: 1 - 2 (x^2 + y^2)
            up = 1.0 - 2.0 * (row[8] * row[8] + row[9] * row[9])
            if row[6] < -self.crash_speed:
                return RunStatus.CRASHED, f"hit the ground at {-row[6]:.2f} m/s at t = {row[0]:.3f} s"
            if up < 0.0:
                return RunStatus.CRASHED, f"on the ground upside down at t = {row[0]:.3f} s"
        return None

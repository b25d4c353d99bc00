"""The lockstep simulator: physics at a fixed rate, every component at its own rate, one deterministic clock."""

from __future__ import annotations

import enum
import math
import sys
import time
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Iterable

import numpy as np

from .components import Bus, Component, Estimator, Recorder, _StateUser
from .messages import ActuatorCommand, Odometry, Topics
from .quadrotor import Quadrotor
from .worlds.collision import CollisionChecker, Contact

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
        shapes = {np.shape(v) for v in values}
        out[f.name] = np.asarray(values) if len(shapes) == 1 else values
    return out


class Simulator:
    """Advances ``vehicle`` at ``physics_rate_hz`` and runs the added components at their rates.

    The vehicle's rotor-speed input is the latest :class:`~cufund.messages.ActuatorCommand` on
    ``Topics.ACTUATOR_COMMAND`` (held over each physics step; before the first one, the rotor speeds at the
    start of the run). Ground truth (with the true accelerations of the last physics step, which inertial
    sensors read) is published on ``Topics.GROUND_TRUTH`` at every tick where a component
    runs. Set the initial state through ``vehicle`` (e.g. ``vehicle.hover(p_W)``) before :meth:`run`.

    Args:
        vehicle: the plant.
        physics_rate_hz: physics steps per second; every component rate must divide it.
        record_rate_hz: ground-truth sampling rate for the result (defaults to the physics rate).
        record_topics: topics whose every message is kept in the result.
        collision: checks the vehicle against a world's meshes (build it with ``ignore_labels=("floor",
            "ground")`` to leave landing to the dynamics' ground plane).
        collision_rate_hz: how often the collision check runs (each check costs ~20 us; at 250 Hz a vehicle at
            5 m/s moves 2 cm between checks).
    """

    def __init__(self, vehicle: Quadrotor, physics_rate_hz: float = 1000.0, record_rate_hz: float | None = None,
                 record_topics: Iterable[str] = (), collision: CollisionChecker | None = None,
                 collision_rate_hz: float = 250.0) -> None:
        if not isinstance(vehicle, Quadrotor):
            raise TypeError(f"vehicle must be a cufund.Quadrotor, got {type(vehicle).__name__}")
        if not (isinstance(physics_rate_hz, (int, float)) and math.isfinite(physics_rate_hz) and physics_rate_hz > 0):
            raise ValueError(f"physics_rate_hz must be a finite number > 0, got {physics_rate_hz!r}")
        self.vehicle = vehicle
        self.physics_rate_hz = float(physics_rate_hz)
        self.record_period = self._period("record_rate_hz", record_rate_hz or physics_rate_hz)
        self.record_topics = tuple(record_topics)
        if collision is not None and not isinstance(collision, CollisionChecker):
            raise TypeError(f"collision must be a cufund.worlds.CollisionChecker, got {type(collision).__name__}")
        self.collision = collision
        """The vehicle's shape against a world: any penetration ends the run CRASHED with the contact."""
        self.collision_period = self._period("collision_rate_hz", collision_rate_hz)
        self.components: list[Component] = []
        self.crash_speed = 1.0
        """Downward speed at ground contact above which a run counts as crashed [m/s]."""
        self.max_distance = 1e4
        """Distance from the origin beyond which a run counts as diverged [m]."""
        self.max_body_rate = 1e3
        """Body rate beyond which a run counts as diverged [rad/s]."""

    def _period(self, name: str, rate_hz: float) -> int:
        if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"{name} must be a finite number > 0 [Hz], got {rate_hz!r}")
        ratio = self.physics_rate_hz / rate_hz
        k = round(ratio)
        if k < 1 or abs(ratio - k) > 1e-9 * ratio:
            raise ValueError(f"{name} must divide the physics rate {self.physics_rate_hz:g} Hz exactly, got {rate_hz:g} Hz")
        return k

    def add(self, component: Component) -> Component:
        """Attaches ``component``; it runs after those added before it within a tick. Returns it."""
        if not isinstance(component, Component):
            raise TypeError(f"component must implement cufund.components.Component, got {type(component).__name__}")
        self._period(f"{type(component).__name__}.rate_hz", component.rate_hz)
        self.components.append(component)
        return component

    def _resolve_state_topics(self) -> None:
        estimators = [c for c in self.components if isinstance(c, Estimator)]
        for c in self.components:
            if not isinstance(c, _StateUser):
                continue
            if c.state_topic is not None:
                c.active_state_topic = c.state_topic
            elif len(estimators) == 1:
                c.active_state_topic = estimators[0].topic
            elif not estimators:
                c.active_state_topic = Topics.GROUND_TRUTH
            else:
                raise ValueError(f"{type(c).__name__}.state_topic must be set when several estimators are attached "
                                 f"({', '.join(e.topic for e in estimators)})")

    def run(self, duration: float, done: Callable[[float, Odometry], bool] | None = None,
            progress: bool = False) -> SimulationResult:
        """Simulates up to ``duration`` [s] from the vehicle's current state and time.

        ``done(t, truth)`` is checked at every ground-truth record; when it holds the run ends COMPLETED.
        ``progress`` draws a progress bar on stderr.
        """
        if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
            raise ValueError(f"duration must be a finite number > 0 [s], got {duration!r}")
        self._resolve_state_topics()
        for c in self.components:
            c.reset()
        quad = self.vehicle
        s = quad.state
        accel_W, alpha_B = quad.accel_W, quad.alpha_B
        dt = 1.0 / self.physics_rate_hz
        n_steps = int(round(duration * self.physics_rate_hz))
        schedule = [(self._period(type(c).__name__, c.rate_hz), c.step) for c in self.components]
        bus = Bus(self.record_topics)
        t0 = quad.t
        cmd = s.rotor_speeds.copy()
        rec_every = self.record_period
        collision, coll_every, contact = self.collision, self.collision_period, None
        n_rec = n_steps // rec_every + 2  # + a row for the state at a collision
        hist = np.empty((n_rec, 18))
        n_written = 0
        status, message = (RunStatus.COMPLETED if done is None else RunStatus.TIMEOUT), "duration elapsed"
        ground_truth = Topics.GROUND_TRUTH
        actuator = Topics.ACTUATOR_COMMAND
        last_bar = -1

        def snapshot(t: float) -> Odometry:
            """Ground truth now, with the true accelerations of the last physics step."""
            return Odometry(t, s.p.copy(), s.v.copy(), s.q.copy(), s.w.copy(), accel_W.copy(), alpha_B.copy())

        def write_row(i: int, t: float) -> np.ndarray:
            row = hist[i]
            row[0] = t
            row[1:4], row[4:7], row[7:11], row[11:14], row[14:18] = s.p, s.v, s.q, s.w, s.rotor_speeds
            return row

        wall0 = time.perf_counter()
        k = 0
        for k in range(n_steps + 1):
            t = t0 + k * dt
            truth = None
            if k < n_steps:
                for period, step in schedule:
                    if k % period == 0:
                        if truth is None:
                            truth = snapshot(t)
                            bus.publish(ground_truth, truth)
                        step(t, bus)
            if collision is not None and k % coll_every == 0:
                hit = collision.check(s.p, s.q)
                if hit is not None and hit.distance < 0.0:
                    contact = hit
                    status = RunStatus.CRASHED
                    message = (f"collided with {hit.label!r} (object {hit.object_id}) at "
                               f"({hit.point_W[0]:.3f}, {hit.point_W[1]:.3f}, {hit.point_W[2]:.3f}) m at t = {t:.3f} s")
                    write_row(n_written, t)
                    n_written += 1
                    break
            if k % rec_every == 0:
                row = write_row(n_written, t)
                n_written += 1
                bad = self._check(row)
                if bad is not None:
                    status, message = bad
                    break
                if done is not None:
                    if truth is None:
                        truth = snapshot(t)
                    if done(t, truth):
                        status, message = RunStatus.COMPLETED, "done condition met"
                        break
            if k == n_steps:
                break
            act: ActuatorCommand | None = bus.get(actuator)
            if act is not None:
                cmd = act.rotor_speeds
            quad.step(dt, cmd)
            if progress and (10 * 40 * k) // n_steps != last_bar:
                last_bar = (10 * 40 * k) // n_steps
                done_chars = last_bar // 10
                sys.stderr.write(f"\r[{'#' * done_chars}{'.' * (40 - done_chars)}] {t - t0:7.2f} / {duration:.2f} s")
                sys.stderr.flush()
        wall = time.perf_counter() - wall0
        if progress:
            sys.stderr.write("\n")
        h = hist[:n_written]
        states = {"t": h[:, 0], "p_W": h[:, 1:4], "v_W": h[:, 4:7], "q_WB": h[:, 7:11], "w_B": h[:, 11:14],
                  "rotor_speeds": h[:, 14:18]}
        topics = {topic: _stack(bus.recorded(topic)) for topic in self.record_topics}
        recordings = {c.name: c.histories() for c in self.components if isinstance(c, Recorder)}
        return SimulationResult(status=status, sim_time_s=float(h[-1, 0] - t0), wall_time_s=wall, states=states,
                                topics=topics, recordings=recordings, message=message, contact=contact)

    def _check(self, row: np.ndarray) -> tuple[RunStatus, str] | None:
        if not math.isfinite(float(row.sum())):
            return RunStatus.DIVERGED, f"non-finite state at t = {row[0]:.3f} s"
        if abs(row[1]) > self.max_distance or abs(row[2]) > self.max_distance or abs(row[3]) > self.max_distance:
            return RunStatus.DIVERGED, f"vehicle left the {self.max_distance:g} m bounds at t = {row[0]:.3f} s"
        if max(abs(row[11]), abs(row[12]), abs(row[13])) > self.max_body_rate:
            return RunStatus.DIVERGED, f"body rate above {self.max_body_rate:g} rad/s at t = {row[0]:.3f} s"
        if self.vehicle.params.ground_plane and row[3] <= 0.05:
            # body z axis's world z component: 1 - 2 (x^2 + y^2)
            up = 1.0 - 2.0 * (row[8] * row[8] + row[9] * row[9])
            if row[6] < -self.crash_speed:
                return RunStatus.CRASHED, f"hit the ground at {-row[6]:.2f} m/s at t = {row[0]:.3f} s"
            if up < 0.0:
                return RunStatus.CRASHED, f"on the ground upside down at t = {row[0]:.3f} s"
        return None

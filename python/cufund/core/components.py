"""Component interfaces: what a user implements to plug an algorithm into :class:`cufund.Simulator`.

A component runs periodically at ``rate_hz`` (any positive rate), first at ``phase_s`` after the start of a run,
and talks to the others only through typed messages (:mod:`cufund.core.messages`), like a node in the paper's ROS
graph. It declares what it reads (``inputs``, and ``optional_inputs`` that need no publisher) and what it
publishes (``outputs``); what it publishes becomes visible ``latency_s`` later. Within one instant the simulator
runs components in the order their zero-latency connections require (producers before consumers), whatever the
order they were added in. Each kind below has one method to implement; ``cufund/templates/`` holds one
commented, working template per kind.

In ``step(t, bus)``: ``bus.latest(topic)`` is the newest visible message, ``bus.subscribe(topic)`` (once, in
:meth:`Component.setup`) gives a queue with every message, ``bus.publish(topic, msg)`` publishes. Nothing
depends on wall-clock time.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

from .bus import Bus, BusView, Subscription
from .messages import Odometry, Topics

__all__ = [
    "Bus",
    "BusView",
    "Component",
    "Controller",
    "Estimator",
    "Mapper",
    "Planner",
    "Recorder",
    "Sensor",
    "Subscription",
]


class Component(ABC):
    """Anything the simulator runs periodically. Prefer one of the kinds below."""

    name: str = ""
    """The component's name in messages, logs and results (default: its class name)."""
    rate_hz: float = 100.0
    """How often :meth:`step` runs [Hz]; any positive rate."""
    phase_s: float = 0.0
    """Delay of the first run after the start of a run [s], in [0, 1 / rate_hz)."""
    latency_s: float = 0.0
    """What the component publishes at t becomes visible at t + latency_s [s] (processing or transport delay)."""
    inputs: tuple[str, ...] = ()
    """Topics it reads, each of which something must publish."""
    optional_inputs: tuple[str, ...] = ()
    """Topics it reads when something publishes them."""
    outputs: tuple[str, ...] = ()
    """Topics it publishes."""
    reads_truth: ClassVar[bool] = False
    """True for truth consumers (sensor models, recorders, metrics, viewers): they may read ``/truth/`` topics
    when an estimator is configured; flight software may not."""

    @abstractmethod
    def step(self, t: float, bus: BusView) -> None:
        """Runs once at simulated time ``t`` [s]: read inputs from ``bus``, publish outputs to it."""

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Called at the start of every run, before :meth:`setup`."""

    def setup(self, bus: BusView) -> None:  # noqa: B027 - optional hook
        """Called at the start of every run with the component's bus handle: create subscriptions here."""


class Sensor(Component):
    """Turns the true state into a measurement published on ``topic``."""

    topic: str = Topics.IMU
    reads_truth = True

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (Topics.TRUTH_ODOMETRY,)

    @property
    def outputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.topic,)

    @abstractmethod
    def measure(self, t: float, truth: Odometry) -> Any:
        """A measurement message (or None to publish nothing this tick)."""

    def step(self, t: float, bus: BusView) -> None:
        msg = self.measure(t, bus.latest(Topics.TRUTH_ODOMETRY))
        if msg is not None:
            bus.publish(self.topic, msg)


class Estimator(Component):
    """Fuses measurements into a state estimate published on ``topic``. Once an estimator is attached, no
    controller, mapper or planner reads ground truth: the attitude and position loops, mappers and planners use
    its output, and the rate loop the IMU's gyro."""

    topic: str = Topics.ESTIMATE
    extra_outputs: tuple[str, ...] = ()
    """Topics it publishes besides the estimate (e.g. diagnostics)."""

    @property
    def outputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.topic, *self.extra_outputs)

    @abstractmethod
    def estimate(self, t: float, bus: BusView) -> Odometry | None:
        """The current estimate (or None before it is initialised)."""

    def step(self, t: float, bus: BusView) -> None:
        msg = self.estimate(t, bus)
        if msg is not None:
            bus.publish(self.topic, msg)


class _StateUser(Component):
    """A component whose input is the vehicle state, read from ``state_topic``."""

    state_topic: str | None = None
    """Topic of the state input; None picks automatically at run start (the estimator's output when one is
    attached, ground truth otherwise). The simulator stores its choice in ``active_state_topic``."""
    active_state_topic: str = Topics.TRUTH_ODOMETRY
    reads: tuple[str, ...] = ()
    """Topics read besides the state, each of which something must publish."""
    optional_reads: tuple[str, ...] = ()
    """Topics read besides the state when something publishes them."""
    writes: tuple[str, ...] = ()
    """Topics published."""

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.active_state_topic, *self.reads)

    @property
    def optional_inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self.optional_reads)

    @property
    def outputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self.writes)

    def step(self, t: float, bus: BusView) -> None:
        state = bus.latest(self.active_state_topic)
        if state is not None:
            self.update(t, state, bus)

    @abstractmethod
    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        """Runs with the current state (skipped while no state has been published)."""


class Planner(_StateUser):
    """Produces references (e.g. :class:`~cufund.core.messages.TrajectorySetpoint`) for the controllers."""


class Controller(_StateUser):
    """Turns references and the state into commands for the next layer (setpoints or actuator commands)."""


class Mapper(Component):
    """Builds a map from measurements; publishes it (e.g. a :class:`~cufund.core.messages.MapUpdate`) for planners."""

    @abstractmethod
    def integrate(self, t: float, bus: BusView) -> None:
        """Reads new measurements from ``bus`` and updates the map."""

    def step(self, t: float, bus: BusView) -> None:
        self.integrate(t, bus)


class Recorder(Component):
    """Keeps what it reads from the bus at its own rate; the simulator puts :meth:`histories` into
    ``SimulationResult.recordings[name]``. A truth consumer: it may read ``/truth/`` topics. (To keep every
    message of a topic, pass the topic to the simulator's ``record_topics`` instead.)"""

    reads_truth = True

    @abstractmethod
    def record(self, t: float, bus: BusView) -> None:
        """Reads and stores."""

    @abstractmethod
    def histories(self) -> dict[str, Any]:
        """What was recorded, as numpy arrays."""

    def step(self, t: float, bus: BusView) -> None:
        self.record(t, bus)

"""Component interfaces: what a user implements to plug an algorithm into :class:`cufund.Simulator`.

A component runs at its own rate ``rate_hz`` on the simulator's lockstep clock (which must divide the physics
rate) and talks to the others only through typed messages on named topics (:mod:`cufund.messages`), like a
node in the paper's ROS graph. Each kind below has one method to implement; ``cufund/templates/`` holds one
commented, working template per kind.

Within a tick, components run in the order they were added; a message published in a tick is visible to
components that run after it in that tick and to every later tick (latest-value semantics, like a ROS topic
with queue size 1). Nothing depends on wall-clock time.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

from .messages import Odometry, Topics

__all__ = ["Bus", "Component", "Controller", "Estimator", "Mapper", "Planner", "Recorder", "Sensor"]


class Bus:
    """Latest message per topic, plus the list of publications on recorded topics."""

    __slots__ = ("_latest", "_recorded")

    def __init__(self, record: tuple[str, ...] = ()) -> None:
        self._latest: dict[str, Any] = {}
        self._recorded: dict[str, list[Any]] = {topic: [] for topic in record}

    def publish(self, topic: str, message: Any) -> None:
        """Makes ``message`` the latest on ``topic``."""
        self._latest[topic] = message
        rec = self._recorded.get(topic)
        if rec is not None:
            rec.append(message)

    def get(self, topic: str) -> Any:
        """The latest message on ``topic``, or None if nothing was published yet."""
        return self._latest.get(topic)

    def recorded(self, topic: str) -> list[Any]:
        """Every message published on a recorded topic, in order."""
        return self._recorded[topic]


class Component(ABC):
    """Anything the simulator runs periodically. Prefer one of the kinds below."""

    name: str = "component"
    rate_hz: float = 100.0

    @abstractmethod
    def step(self, t: float, bus: Bus) -> None:
        """Runs once at simulated time ``t`` [s]: read inputs from ``bus``, publish outputs to it."""

    def reset(self) -> None:  # noqa: B027 - optional hook
        """Called at the start of every run."""


class Sensor(Component):
    """Turns the true state into a measurement published on ``topic``."""

    topic: str = Topics.IMU

    @abstractmethod
    def measure(self, t: float, truth: Odometry) -> Any:
        """A measurement message (or None to publish nothing this tick)."""

    def step(self, t: float, bus: Bus) -> None:
        msg = self.measure(t, bus.get(Topics.GROUND_TRUTH))
        if msg is not None:
            bus.publish(self.topic, msg)


class Estimator(Component):
    """Fuses measurements into a state estimate published on ``topic``. Once an estimator is added, controllers
    and planners with an automatic state topic use its output, never ground truth."""

    topic: str = Topics.ESTIMATE

    @abstractmethod
    def estimate(self, t: float, bus: Bus) -> Odometry | None:
        """The current estimate (or None before it is initialised)."""

    def step(self, t: float, bus: Bus) -> None:
        msg = self.estimate(t, bus)
        if msg is not None:
            bus.publish(self.topic, msg)


class _StateUser(Component):
    """A component whose input is the vehicle state, read from ``state_topic``."""

    state_topic: str | None = None
    """Topic of the state input; None picks automatically at run start (the estimator's output when one is
    attached, ground truth otherwise). The simulator stores its choice in ``active_state_topic``."""
    active_state_topic: str = Topics.GROUND_TRUTH

    def step(self, t: float, bus: Bus) -> None:
        state = bus.get(self.active_state_topic)
        if state is not None:
            self.update(t, state, bus)

    @abstractmethod
    def update(self, t: float, state: Odometry, bus: Bus) -> None:
        """Runs with the current state (skipped while no state has been published)."""


class Planner(_StateUser):
    """Produces references (e.g. :class:`~cufund.messages.TrajectorySetpoint`) for the controllers."""


class Controller(_StateUser):
    """Turns references and the state into commands for the next layer (setpoints or actuator commands)."""


class Mapper(Component):
    """Builds a map from measurements; publishes it or exposes it to planners."""

    @abstractmethod
    def integrate(self, t: float, bus: Bus) -> None:
        """Reads new measurements from ``bus`` and updates the map."""

    def step(self, t: float, bus: Bus) -> None:
        self.integrate(t, bus)


class Recorder(Component):
    """Keeps what it reads from the bus at its own rate; the simulator puts :meth:`histories` into
    ``SimulationResult.recordings[name]``. (To keep every message of a topic, pass the topic to the simulator's
    ``record_topics`` instead.)"""

    @abstractmethod
    def record(self, t: float, bus: Bus) -> None:
        """Reads and stores."""

    @abstractmethod
    def histories(self) -> dict[str, Any]:
        """What was recorded, as numpy arrays."""

    def step(self, t: float, bus: Bus) -> None:
        self.record(t, bus)

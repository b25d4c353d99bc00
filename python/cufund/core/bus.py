"""The message bus: every subscriber receives every message in order, with per-component access control.

A message published at simulated time t by a component with output latency L becomes *visible* at t + L: from
then on it is the topic's :meth:`Bus.latest` and it is queued for every subscription. Queues are bounded; a
message pushed out of a full queue is counted in :attr:`Subscription.dropped` (and in the run's result), never
lost silently. Components talk to the bus through a :class:`BusView` that lets them read only their declared
inputs and publish only their declared outputs, and that refuses ``/truth/`` topics to flight software once an
estimator is configured.
"""

from __future__ import annotations

import heapq
from collections import deque
from collections.abc import Iterable
from typing import Any

from .topics import is_truth

__all__ = ["Bus", "BusView", "Subscription", "TopicAccessError", "TruthAccessError"]

DEFAULT_QUEUE_SIZE = 10_000
"""Messages a subscription holds before it drops the oldest (20 s of 500 Hz IMU samples)."""


class TopicAccessError(RuntimeError):
    """A component read or published a topic it did not declare (in ``inputs`` / ``outputs``)."""


class TruthAccessError(TopicAccessError):
    """Flight software (anything but a truth consumer) read a ``/truth/`` topic while an estimator is configured."""


class Subscription:
    """Every message that became visible on ``topic`` since the last :meth:`take`, oldest first."""

    __slots__ = ("topic", "owner", "maxlen", "dropped", "_queue")

    def __init__(self, topic: str, owner: str, maxlen: int = DEFAULT_QUEUE_SIZE) -> None:
        if isinstance(maxlen, bool) or not isinstance(maxlen, int) or maxlen < 1:
            raise ValueError(f"maxlen must be an integer >= 1, got {maxlen!r}")
        self.topic, self.owner, self.maxlen = topic, owner, maxlen
        self.dropped = 0
        """Messages pushed out of the full queue before they were taken."""
        self._queue: deque[tuple[int, Any]] = deque()

    def _push(self, visible_ns: int, message: Any) -> None:
        q = self._queue
        if len(q) >= self.maxlen:
            q.popleft()
            self.dropped += 1
        q.append((visible_ns, message))

    def take(self) -> list[Any]:
        """The queued messages, in the order they became visible; empties the queue."""
        q = self._queue
        if not q:
            return []
        out = [m for _, m in q]
        q.clear()
        return out

    def take_stamped(self) -> list[tuple[float, Any]]:
        """Like :meth:`take`, with the time [s] at which each message became visible."""
        out = [(ns / 1e9, m) for ns, m in self._queue]
        self._queue.clear()
        return out

    def __len__(self) -> int:
        return len(self._queue)


class Bus:
    """Topics, their latest visible message, subscriptions, messages in flight, recording and logging.

    ``record``: topics whose every visible message is kept in memory (:meth:`recorded`). ``logger``: an object
    with ``write(topic, message, log_time_ns, publish_time_ns)`` (e.g. :class:`cufund.logs.McapLogger`) that
    receives every visible message of the topics ``log_topics`` selects (None: all).
    """

    def __init__(self, record: Iterable[str] = (), logger: Any = None, log_topics: Iterable[str] | None = None) -> None:
        self.now_ns = 0
        """The current simulated time [ns]; the simulator advances it."""
        self._latest: dict[str, Any] = {}
        self._subs: dict[str, list[Subscription]] = {}
        self._recorded: dict[str, list[Any]] = {str(t): [] for t in record}
        self._pending: list[tuple[int, int, str, Any, int]] = []
        self._seq = 0
        self.logger = logger
        self._log_topics = None if log_topics is None else frozenset(str(t) for t in log_topics)
        self.subscriptions: list[Subscription] = []

    # -- publishing --------------------------------------------------------------------------------------------
    def publish(self, topic: str, message: Any, latency_ns: int = 0) -> None:
        """Publishes ``message`` now; it becomes visible ``latency_ns`` later. A typed :class:`Topic` checks the
        message's type."""
        kind = getattr(topic, "type", object)
        if kind is not object and not isinstance(message, kind):
            raise TypeError(f"{topic} carries {kind.__name__} messages, got {type(message).__name__}")
        if latency_ns <= 0:
            self.deliver(topic, message, self.now_ns, self.now_ns)
        else:
            self._enqueue(topic, message, latency_ns)

    def _enqueue(self, topic: str, message: Any, latency_ns: int) -> None:
        self._seq += 1
        heapq.heappush(self._pending, (self.now_ns + latency_ns, self._seq, topic, message, self.now_ns))

    def deliver(self, topic: str, message: Any, visible_ns: int, publish_ns: int) -> None:
        """Makes ``message`` visible on ``topic`` now: the topic's latest, queued for its subscriptions, recorded,
        logged with ``visible_ns`` as its log time. No type check and no latency: for a producer that delivers at
        the bus's current time a message it guarantees to be of the topic's type (the simulator's ground truth;
        :meth:`publish` and :meth:`release` end here)."""
        self._latest[topic] = message
        subs = self._subs.get(topic)
        if subs:
            for s in subs:
                s._push(visible_ns, message)
        rec = self._recorded.get(topic)
        if rec is not None:
            rec.append(message)
        logger = self.logger
        if logger is not None and (self._log_topics is None or topic in self._log_topics):
            logger.write(topic, message, visible_ns, publish_ns)

    def next_visible_ns(self) -> int | None:
        """When the earliest message in flight becomes visible [ns], or None."""
        return self._pending[0][0] if self._pending else None

    def release(self, now_ns: int) -> None:
        """Makes every message in flight whose time has come visible, in order of visibility then publication."""
        pending = self._pending
        while pending and pending[0][0] <= now_ns:
            visible, _, topic, message, published = heapq.heappop(pending)
            self.deliver(topic, message, visible, published)

    # -- reading -----------------------------------------------------------------------------------------------
    def latest(self, topic: str) -> Any:
        """The newest visible message on ``topic``, or None."""
        return self._latest.get(topic)

    get = latest

    def subscribe(self, topic: str, owner: str = "user", maxlen: int = DEFAULT_QUEUE_SIZE) -> Subscription:
        """A queue that receives every message visible on ``topic`` from now on."""
        sub = Subscription(str(topic), owner, maxlen)
        self._subs.setdefault(str(topic), []).append(sub)
        self.subscriptions.append(sub)
        return sub

    def has_consumer(self, topic: str) -> bool:
        """Whether a message on ``topic`` reaches anything beyond :meth:`latest`: the topic is recorded, subscribed
        to, or logged. (A producer may skip a message no consumer could tell apart from the last one, e.g. the
        simulator's ground truth at instants where no component reads it.)"""
        t = str(topic)
        if t in self._recorded or self._subs.get(t):
            return True
        return self.logger is not None and (self._log_topics is None or t in self._log_topics)

    def recorded(self, topic: str) -> list[Any]:
        """Every visible message on a recorded topic, in order."""
        return self._recorded[topic]

    def dropped(self) -> dict[str, int]:
        """Messages dropped from full queues, by ``owner:topic``, for the subscriptions that dropped any."""
        return {f"{s.owner}:{s.topic}": s.dropped for s in self.subscriptions if s.dropped}


class BusView:
    """One component's handle on the bus: reads only ``inputs``, publishes only ``outputs`` (with the component's
    latency). ``deny_truth``: reading any ``/truth/`` topic raises :class:`TruthAccessError`."""

    __slots__ = ("_bus", "_latest", "owner", "_readable", "_writable", "_latency_ns", "_deny_truth", "reads")

    def __init__(
        self,
        bus: Bus,
        owner: str,
        inputs: Iterable[str],
        outputs: Iterable[str],
        latency_ns: int = 0,
        deny_truth: bool = False,
    ) -> None:
        self._bus, self.owner = bus, owner
        self._latest = bus._latest
        self._readable = frozenset(str(t) for t in inputs)
        self._writable = {str(t): (t, getattr(t, "type", object)) for t in outputs}
        self._latency_ns = int(latency_ns)
        self._deny_truth = deny_truth
        self.reads: set[str] = set()
        """Every topic this component has read (latest or subscribed)."""

    @property
    def inputs(self) -> frozenset[str]:
        """The topics this component may read (its declared inputs)."""
        return self._readable

    def _check_read(self, topic: str) -> None:
        if self._deny_truth and is_truth(topic):
            raise TruthAccessError(
                f"{self.owner} read the ground-truth topic {topic}; with an estimator configured "
                "only truth consumers (sensor models, recorders, metrics) may"
            )
        if topic not in self._readable:
            raise TopicAccessError(
                f"{self.owner} read {topic}, which is not among its declared inputs "
                f"({', '.join(sorted(self._readable)) or 'none'})"
            )
        self.reads.add(topic)

    def latest(self, topic: str) -> Any:
        """The newest visible message on ``topic`` (a declared input), or None."""
        if topic not in self.reads:
            self._check_read(topic)
        return self._latest.get(topic)

    get = latest

    def subscribe(self, topic: str, maxlen: int = DEFAULT_QUEUE_SIZE) -> Subscription:
        """A queue of every message on ``topic`` (a declared input) from now on; call once, in ``setup``."""
        self._check_read(str(topic))
        return self._bus.subscribe(topic, self.owner, maxlen)

    def publish(self, topic: str, message: Any) -> None:
        """Publishes ``message`` on ``topic`` (a declared output); visible after the component's latency."""
        entry = self._writable.get(topic)
        if entry is None:
            raise TopicAccessError(
                f"{self.owner} published on {topic}, which is not among its declared outputs "
                f"({', '.join(sorted(self._writable)) or 'none'})"
            )
        typed, kind = entry
        if message.__class__ is not kind and kind is not object and not isinstance(message, kind):
            raise TypeError(f"{typed} carries {kind.__name__} messages, got {type(message).__name__}")
        bus = self._bus
        if self._latency_ns:
            bus._enqueue(typed, message, self._latency_ns)
        else:
            bus.deliver(typed, message, bus.now_ns, bus.now_ns)

    def publish_at(self, topic: str, message: Any, visible_ns: int, publish_ns: int | None = None) -> None:
        """Schedules ``message`` (on a declared output) to become visible at ``visible_ns`` (>= now), as if it had
        been published at ``publish_ns``: for replaying a log at its own times."""
        entry = self._writable.get(topic)
        if entry is None:
            raise TopicAccessError(f"{self.owner} published on {topic}, which is not among its declared outputs")
        bus = self._bus
        if visible_ns < bus.now_ns:
            raise ValueError(
                f"{self.owner}: a message on {topic} cannot become visible in the past "
                f"({visible_ns} ns < now {bus.now_ns} ns)"
            )
        bus._seq += 1
        heapq.heappush(
            bus._pending,
            (int(visible_ns), bus._seq, entry[0], message, int(visible_ns if publish_ns is None else publish_ns)),
        )

    @property
    def now(self) -> float:
        """The current simulated time [s]."""
        return self._bus.now_ns / 1e9
